#pragma once

// GNSS noise from the residuals (docs/calibration.md, Eq. N2). A receiver states each fix's
// std from its own model, which leaves out multipath, the atmosphere and a poor view of the
// sky, and it states the horizontal and the vertical apart (the satellite geometry weighs on
// the vertical most). About a solved trajectory the GNSS rows, whitened by the stated std,
// have a robust sigma s = 1.4826 median |r| per axis group, the horizontal rows (east, north)
// and the vertical one; the multipath fixes the loss down-weights leave it alone. Where s is
// at least kMinGnssNoiseScale over at least kMinGnssNoiseRows rows, that group's sigma is
// scaled by s, as the IMU's and the wheels' noise from the data (pipeline/clock_initialization.h).
//
// When the model is right and the loss leaves the rows alone, the residuals are fitted: a row
// of leverage h has E r^2 = (1 - h) s^2, so s reads low. Rows a robust loss down-weights are
// not fitted, and a trajectory they hold loosely can wander: with the std stated far too small
// s can read somewhat high (4.8 for 4 on a platform at rest held by the fixes alone). A model
// error the fixes see (a lever arm or a clock held wrong) reads as scatter too: the fixes then
// count for less. A stated std that is too large is kept: the rows count for less than they
// could, which no sigma hides.

#include <Eigen/Core>
#include <cstddef>

#include "autocal/common/running_median.h"

namespace autocal {
namespace estimation {

constexpr double kMinGnssNoiseScale = 1.5;

// The fewest rows of an axis group that are judged. Rows that scatter as stated read
// s >= kMinGnssNoiseScale when half of them (the median's n - n/2) exceed |r| = 1.5 / 1.4826,
// each with the chance q = 2 (1 - Phi(1.0118)) = 0.312: the binomial tail P(B(n, q) >= n - n/2)
// is under 0.001 from n = 67 on, for every larger n (0.00109 at 66).
constexpr size_t kMinGnssNoiseRows = 67;

// What multiplies the fixes' stated std, per axis group.
struct GnssStdScale {
  double horizontal = 1.0;  // east and north
  double vertical = 1.0;    // up
  bool IsOne() const { return horizontal == 1.0 && vertical == 1.0; }
  bool operator==(const GnssStdScale& o) const {
    return horizontal == o.horizontal && vertical == o.vertical;
  }
  // Throws autocal::Error unless both are positive and finite.
  void Check(const char* what) const;
  Eigen::Vector3d Applied(const Eigen::Vector3d& sigma_enu_m) const {
    return {horizontal * sigma_enu_m.x(), horizontal * sigma_enu_m.y(), vertical * sigma_enu_m.z()};
  }
};

// One axis group's rows: their robust sigma, their count and the scale they call for (s, or 1
// below kMinGnssNoiseScale or kMinGnssNoiseRows).
struct GnssAxisNoise {
  double robust_sigma = 0.0;
  size_t rows = 0;
  double scale = 1.0;
};
struct GnssNoiseFromResiduals {
  GnssAxisNoise horizontal;
  GnssAxisNoise vertical;
  GnssStdScale Scale() const { return {horizontal.scale, vertical.scale}; }
};

// Eq. N2 over rows added one at a time, whitened by the fixes' stated std (without the loss);
// O(log n) per row. Non-finite rows are refused (false) and not counted.
class GnssRowScatter {
 public:
  bool AddHorizontal(double whitened);
  bool AddVertical(double whitened);
  GnssNoiseFromResiduals Noise() const;

 private:
  RunningMedian horizontal_;
  RunningMedian vertical_;
};

}  // namespace estimation
}  // namespace autocal
