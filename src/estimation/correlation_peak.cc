#include "estimation/correlation_peak.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/format.h"

namespace autocal {
namespace estimation {
namespace internal {

double Pearson(const std::vector<double>& a, const std::vector<double>& b) {
  const double n = static_cast<double>(a.size());
  const double mean_a = std::accumulate(a.begin(), a.end(), 0.0) / n;
  const double mean_b = std::accumulate(b.begin(), b.end(), 0.0) / n;
  double sab = 0.0, saa = 0.0, sbb = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - mean_a) * (b[i] - mean_b);
    saa += (a[i] - mean_a) * (a[i] - mean_a);
    sbb += (b[i] - mean_b) * (b[i] - mean_b);
  }
  if (saa <= 0.0 || sbb <= 0.0) return 0.0;
  return sab / std::sqrt(saa * sbb);
}

namespace {

// The number of whole steps in half_range_s, so that the scan stays inside the range its
// caller checked coverage for. Throws autocal::Error for a range or step that is not finite
// and positive, a step longer than the range, or more than kMaxScanSteps steps.
int ScanSteps(double center_s, double half_range_s, double step_s) {
  const auto message = [&](const std::string& what) {
    return "ScanCorrelation: " + what + " (centre " + FormatShort(center_s) + " s, half range " +
           FormatShort(half_range_s) + " s, step " + FormatShort(step_s) + " s)";
  };
  if (!std::isfinite(center_s)) throw Error(message("the centre must be finite"));
  if (!(std::isfinite(half_range_s) && half_range_s > 0.0)) {
    throw Error(message("the half range must be finite and positive"));
  }
  if (!(std::isfinite(step_s) && step_s > 0.0)) {
    throw Error(message("the step must be finite and positive"));
  }
  if (step_s > half_range_s) throw Error(message("the step must not exceed the half range"));
  const double ratio = half_range_s / step_s;
  if (ratio > kMaxScanSteps) {
    throw Error(
        message("at most " + std::to_string(kMaxScanSteps) + " steps either side are scanned"));
  }
  // A step that divides the range up to rounding (0.1 / 0.001) keeps its last candidate.
  return static_cast<int>(std::floor(ratio * (1.0 + 1e-12)));
}

}  // namespace

CorrelationScan ScanCorrelation(double center_s, double half_range_s, double step_s,
                                const std::function<double(double offset_s)>& correlation_at) {
  CorrelationScan scan;
  const int steps = ScanSteps(center_s, half_range_s, step_s);
  for (int k = -steps; k <= steps; ++k) {
    const double offset_s = center_s + k * step_s;
    scan.offsets_s.push_back(offset_s);
    scan.correlation.push_back(correlation_at(offset_s));
  }
  const auto peak = std::max_element(scan.correlation.begin(), scan.correlation.end());
  const size_t p = static_cast<size_t>(peak - scan.correlation.begin());
  scan.peak = p;
  scan.refined_offset_s = scan.offsets_s[p];
  if (p == 0 || p + 1 == scan.correlation.size()) {
    scan.peak_at_edge = true;
    return scan;
  }
  // Parabola through the peak and its neighbours.
  const double c_minus = scan.correlation[p - 1], c0 = scan.correlation[p],
               c_plus = scan.correlation[p + 1];
  const double curvature = c_minus - 2.0 * c0 + c_plus;
  if (curvature < 0.0) scan.refined_offset_s += 0.5 * step_s * (c_minus - c_plus) / curvature;
  return scan;
}

std::optional<double> FitParabolaPeak(const CorrelationScan& scan) {
  const size_t n = scan.offsets_s.size();
  if (n < 3) return std::nullopt;
  // c = a x^2 + b x + d with x relative to the scan's centre (conditioning).
  const double center_s = scan.offsets_s[n / 2];
  Eigen::MatrixXd A(n, 3);
  Eigen::VectorXd c(n);
  for (size_t i = 0; i < n; ++i) {
    const double x = scan.offsets_s[i] - center_s;
    A.row(static_cast<Eigen::Index>(i)) << x * x, x, 1.0;
    c(static_cast<Eigen::Index>(i)) = scan.correlation[i];
  }
  const Eigen::Vector3d coefficients = A.colPivHouseholderQr().solve(c);
  if (!(coefficients(0) < 0.0)) return std::nullopt;
  const double vertex_s = center_s - 0.5 * coefficients(1) / coefficients(0);
  if (!(vertex_s >= scan.offsets_s.front() && vertex_s <= scan.offsets_s.back())) {
    return std::nullopt;
  }
  return vertex_s;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
