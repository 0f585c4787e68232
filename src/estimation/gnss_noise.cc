#include "autocal/estimation/gnss_noise.h"

#include <cmath>

#include "common/order_statistics.h"

namespace autocal {
namespace estimation {

GnssNoiseFromResiduals GnssNoiseOfRows(const std::vector<double>& whitened) {
  GnssNoiseFromResiduals out;
  if (whitened.empty()) return out;
  std::vector<double> magnitudes;
  magnitudes.reserve(whitened.size());
  for (const double r : whitened) magnitudes.push_back(std::abs(r));
  out.rows = whitened.size();
  out.robust_sigma = 1.4826 * autocal::internal::Median(std::move(magnitudes));
  if (out.robust_sigma >= kMinGnssNoiseScale) out.scale = out.robust_sigma;
  return out;
}

}  // namespace estimation
}  // namespace autocal
