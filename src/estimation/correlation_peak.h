#pragma once

// The correlation search shared by the time-offset estimators (initialization.h and
// clock_offsets.h): a Pearson correlation evaluated on a grid of candidate offsets, its
// highest point, and a parabola through that point and its two neighbours for a
// sub-step offset. Private to src/estimation.

#include <cstddef>
#include <functional>
#include <optional>
#include <vector>

namespace autocal {
namespace estimation {
namespace internal {

// Pearson correlation of two equally long series; 0 when either is constant.
double Pearson(const std::vector<double>& a, const std::vector<double>& b);

struct CorrelationScan {
  std::vector<double> offsets_s;  // center + k * step for k in [-steps, steps]
  std::vector<double> correlation;
  size_t peak = 0;                // index of the highest correlation
  bool peak_at_edge = false;      // the peak is the first or last candidate
  double refined_offset_s = 0.0;  // the peak's offset moved by the parabola (not at an edge)
};

// The most steps either side of the centre a scan takes (2 * 10^6 + 1 evaluations).
constexpr int kMaxScanSteps = 1'000'000;

// Evaluates correlation_at(offset) for offset = center_s + k * step_s, |k| <= steps with
// steps = floor(half_range_s / step_s): every candidate lies inside the half range, also when
// the step does not divide it. Locates the peak; the parabola moves the peak only where it is
// concave (at most half a step either way). Throws autocal::Error unless the centre is
// finite, the half range and the step are finite and positive, the step is at most the half
// range and the half range at most kMaxScanSteps steps.
CorrelationScan ScanCorrelation(double center_s, double half_range_s, double step_s,
                                const std::function<double(double offset_s)>& correlation_at);

// The vertex of the least-squares parabola through every point of the scan: where the
// curve's own scatter from sample to sample (the noise of the interpolated samples) exceeds
// its curvature over three neighbouring candidates, one parabola through many candidates
// still finds the peak. nullopt when the fit is not concave or its vertex lies outside the
// scanned offsets.
std::optional<double> FitParabolaPeak(const CorrelationScan& scan);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
