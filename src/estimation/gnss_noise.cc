#include "autocal/estimation/gnss_noise.h"

#include <cmath>
#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace {

GnssAxisNoise AxisNoise(const RunningMedian& magnitudes) {
  GnssAxisNoise out;
  out.rows = magnitudes.size();
  if (out.rows == 0) return out;
  out.robust_sigma = 1.4826 * magnitudes.Median();
  if (out.rows >= kMinGnssNoiseRows && out.robust_sigma >= kMinGnssNoiseScale) {
    out.scale = out.robust_sigma;
  }
  return out;
}

bool AddTo(double whitened, RunningMedian* magnitudes) {
  if (!std::isfinite(whitened)) return false;
  magnitudes->Add(std::abs(whitened));
  return true;
}

}  // namespace

void GnssStdScale::Check(const char* what) const {
  for (const double s : {horizontal, vertical}) {
    if (!(s > 0.0) || !std::isfinite(s)) {
      throw Error(std::string(what) + ": the GNSS std scale must be positive and finite, got " +
                  std::to_string(horizontal) + " horizontal, " + std::to_string(vertical) +
                  " vertical");
    }
  }
}

bool GnssRowScatter::AddHorizontal(double whitened) { return AddTo(whitened, &horizontal_); }
bool GnssRowScatter::AddVertical(double whitened) { return AddTo(whitened, &vertical_); }

GnssNoiseFromResiduals GnssRowScatter::Noise() const {
  return {AxisNoise(horizontal_), AxisNoise(vertical_)};
}

}  // namespace estimation
}  // namespace autocal
