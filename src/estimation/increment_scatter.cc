#include "autocal/estimation/increment_scatter.h"

#include <algorithm>
#include <cmath>

#include "autocal/common/error.h"
#include "autocal/estimation/calibration_observability.h"
#include "autocal/sensors/calibration_blocks.h"

namespace autocal {
namespace estimation {

namespace internal {

double OrderStatisticQuantile(int m, int n, double tail) {
  if (m < 1 || m > n || !(tail > 0.0) || !(tail < 1.0)) {
    throw Error("OrderStatisticQuantile: needs 1 <= m <= n and 0 < tail < 1, got m " +
                std::to_string(m) + ", n " + std::to_string(n) + ", tail " + std::to_string(tail));
  }
  // P(X_(m) > q) = P(fewer than m of n draws at most q) = sum_{k<m} C(n,k) F^k (1-F)^(n-k),
  // F = P(chi^2(1) <= q) = erf(sqrt(q / 2)); it falls as q grows. The terms in logarithms:
  // C(n, k) overflows a double from n of about a thousand.
  const auto exceeds = [&](double q) {
    const double log_F = std::log(std::erf(std::sqrt(0.5 * q)));
    const double log_1mF = std::log(std::erfc(std::sqrt(0.5 * q)));
    double sum = 0.0;
    for (int k = 0; k < m; ++k) {
      const double log_binomial =
          std::lgamma(n + 1.0) - std::lgamma(k + 1.0) - std::lgamma(n - k + 1.0);
      sum += std::exp(log_binomial + (k > 0 ? k * log_F : 0.0) + (n - k) * log_1mF);
    }
    return sum;
  };
  double low = 0.0, high = 1.0;
  while (exceeds(high) > tail) high *= 2.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (low + high);
    (exceeds(mid) > tail ? low : high) = mid;
  }
  return 0.5 * (low + high);
}

}  // namespace internal

namespace {

// The row block `name` starts at in `covariance`, or -1.
int OffsetOf(const CalibrationCovariance& covariance, const std::string& name) {
  for (size_t b = 0; b < covariance.names.size(); ++b) {
    if (covariance.names[b] == name) return covariance.offsets[b];
  }
  return -1;
}

// Direction k of block `info`: its steps between the checkpoints over their predicted sigma,
// those whose predicted variance is above `floor`.
std::vector<double> NormalizedSteps(const std::vector<CalibrationCheckpoint>& checkpoints,
                                    const sensors::CalibrationBlockInfo& info, int k,
                                    double floor) {
  sensors::Calibration scratch;
  const EstimatedBlock block = BlockOf(info.id, &scratch);
  std::vector<double> z;
  for (size_t j = 0; j + 1 < checkpoints.size(); ++j) {
    const CalibrationCheckpoint& a = checkpoints[j];
    const CalibrationCheckpoint& b = checkpoints[j + 1];
    const int row_a = OffsetOf(a.covariance, info.key);
    const int row_b = OffsetOf(b.covariance, info.key);
    if (row_a < 0 || row_b < 0) continue;
    const double predicted = a.covariance.covariance(row_a + k, row_a + k) -
                             b.covariance.covariance(row_b + k, row_b + k);
    const double step =
        BlockMinus(block, info.const_values(b.value), info.const_values(a.value))(k);
    if (predicted > std::max(floor, 0.0) && std::isfinite(step)) {
      z.push_back(step / std::sqrt(predicted));
    }
  }
  return z;
}

}  // namespace

IncrementScatter ScatterOfIncrements(const std::vector<CalibrationCheckpoint>& checkpoints,
                                     double significance) {
  if (!(significance > 0.0) || !(significance < 1.0)) {
    throw Error("ScatterOfIncrements: significance must lie in (0, 1), got " +
                std::to_string(significance));
  }
  IncrementScatter out;
  if (checkpoints.size() < 2) return out;
  const CalibrationCovariance& last = checkpoints.back().covariance;
  for (size_t b = 0; b < last.names.size(); ++b) {
    const sensors::CalibrationBlockInfo* info = sensors::FindCalibrationBlock(last.names[b]);
    if (info == nullptr) continue;
    for (int k = 0; k < info->tangent_size; ++k) {
      const int row = last.offsets[b] + k;
      const double floor =
          last.covariance(row, row) / (4.0 * static_cast<double>(checkpoints.size() - 1));
      std::vector<double> squares;
      for (const double z : NormalizedSteps(checkpoints, *info, k, floor)) {
        squares.push_back(z * z);
      }
      if (squares.empty()) continue;
      const int n = static_cast<int>(squares.size());
      const int m = (n + 1) / 2;
      std::nth_element(squares.begin(), squares.begin() + (m - 1), squares.end());
      const double median = squares[static_cast<size_t>(m - 1)];
      IncrementScatter::Direction direction;
      direction.block = info->key;
      direction.row = row;
      direction.steps = n;
      direction.ratio = median / internal::OrderStatisticQuantile(m, n, 0.5);
      direction.exceeds = median > internal::OrderStatisticQuantile(m, n, significance);
      out.directions.push_back(direction);
    }
  }
  return out;
}

CalibrationCovariance WidenedForIncrements(const CalibrationCovariance& covariance,
                                           const IncrementScatter& scatter,
                                           const Eigen::VectorXd& max_variance,
                                           std::vector<WidenedDirection>* widened_directions) {
  const Eigen::Index n = covariance.covariance.rows();
  if (max_variance.size() != n) {
    throw Error("WidenedForIncrements: " + std::to_string(max_variance.size()) +
                " variance limits for " + std::to_string(n) + " rows");
  }
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(n);
  std::vector<WidenedDirection> found;
  for (const IncrementScatter::Direction& d : scatter.directions) {
    const double before = d.row < n ? covariance.covariance(d.row, d.row) : 0.0;
    if (!d.exceeds || !(before > 0.0)) continue;
    const double after = std::max(before, std::min(d.ratio * before, max_variance(d.row)));
    scale(d.row) = std::sqrt(after / before);
    if (scale(d.row) > 1.0) found.push_back({d, scale(d.row)});
  }
  CalibrationCovariance out = covariance;
  out.covariance = scale.asDiagonal() * covariance.covariance * scale.asDiagonal();
  std::stable_sort(found.begin(), found.end(),
                   [](const auto& a, const auto& b) { return a.sigma_factor > b.sigma_factor; });
  if (widened_directions != nullptr) *widened_directions = std::move(found);
  return out;
}

}  // namespace estimation
}  // namespace autocal
