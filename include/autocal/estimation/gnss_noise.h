#pragma once

// GNSS noise from the residuals (docs/calibration.md, Eq. N2). A receiver states each fix's
// std from its own model, which leaves out multipath, the atmosphere and a poor view of the
// sky. About a solved trajectory the GNSS rows, whitened by the stated std, have the robust
// sigma s = 1.4826 median |r|; the multipath fixes the loss down-weights leave it alone. When
// s is at least kMinGnssNoiseScale, every GNSS row's sigma is scaled by s, as the IMU's and
// the wheels' noise from the data (pipeline/clock_initialization.h).
//
// The residuals are fitted: a row of leverage h has E r^2 = (1 - h) s^2, so s reads low, never
// high, and the scale does not overstate the scatter. A stated std that is too large is kept:
// the rows then count for less than they could, which no sigma hides.

#include <cstddef>
#include <vector>

namespace autocal {
namespace estimation {

constexpr double kMinGnssNoiseScale = 1.5;

struct GnssNoiseFromResiduals {
  double robust_sigma = 0.0;  // s, of the rows whitened by the stated std
  size_t rows = 0;
  double scale = 1.0;  // s when s >= kMinGnssNoiseScale, else 1
};

// Eq. N2 over `whitened`, GNSS rows' residuals whitened by the fixes' stated std (without the
// loss). Nothing (scale 1, no rows) when it is empty.
GnssNoiseFromResiduals GnssNoiseOfRows(const std::vector<double>& whitened);

// The fewest rows a stream decides on (SlidingWindowOptions::gnss_noise_from_residuals). Rows
// that scatter as stated read s >= kMinGnssNoiseScale when half of them (the median's
// n - n/2) exceed |r| = 1.5 / 1.4826, each with the chance q = 2 (1 - Phi(1.0118)) = 0.312:
// the binomial tail P(B(n, q) >= n - n/2) is under 0.001 from n = 67 on, for every larger n.
constexpr size_t kMinGnssNoiseRows = 67;

}  // namespace estimation
}  // namespace autocal
