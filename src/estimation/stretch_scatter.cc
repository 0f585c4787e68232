#include "autocal/estimation/stretch_scatter.h"

#include <algorithm>
#include <cmath>

#include "autocal/common/chi_square.h"
#include "autocal/common/error.h"
#include "autocal/estimation/calibration_observability.h"

namespace autocal {
namespace estimation {

namespace {

// observed_cc / expected_cc when it exceeds chance at `significance`, else 1 (Eq. C8).
double SignificantRatio(const StretchScatter::Source& source, int c, double significance) {
  if (!JudgesScatter(source, c)) return 1.0;
  const double expected = source.expected(c, c);
  const double ratio = source.observed(c, c) / expected;
  const double dof = std::max(1.0, source.degrees_of_freedom(c));
  const double limit = ChiSquareQuantile(significance, dof) / dof;
  return ratio > limit ? ratio : 1.0;
}

// The smallest sigma factor a widening is reported with.
constexpr double kReportedSigmaFactor = 1.01;

}  // namespace

bool JudgesScatter(const StretchScatter::Source& source, int c) {
  const double expected = source.expected(c, c);
  return expected > 1e-3 * source.model(c, c) && expected > 0.0;
}

BlockCovariance WidenedForScatter(const BlockCovariance& covariance, const StretchScatter& scatter,
                                  double significance, const Eigen::VectorXd& max_variance,
                                  std::vector<ScatterExcess>* excess) {
  if (!covariance.ok || !scatter.ok) return covariance;
  const Eigen::Index n = covariance.matrix.rows();
  if (max_variance.size() != n || scatter.variance.size() != n) {
    throw Error("WidenedForScatter: " + std::to_string(max_variance.size()) +
                " variance limits and " + std::to_string(scatter.variance.size()) +
                " variances for " + std::to_string(n) + " coordinates");
  }
  // A widened variance as far as the limit allows, never below the one before.
  const auto bounded = [&](int c, double widened) {
    return std::max(covariance.matrix(c, c), std::min(widened, max_variance(c)));
  };
  Eigen::VectorXd variance = covariance.matrix.diagonal();
  std::vector<ScatterExcess> found;
  for (const StretchScatter::Source& source : scatter.sources) {
    if (source.observed.rows() != n) continue;
    for (int c = 0; c < n; ++c) {
      const double before = covariance.matrix(c, c);
      const double ratio = SignificantRatio(source, c, significance);
      if (ratio == 1.0 || !(before > 0.0) || !(scatter.variance(c) > 0.0)) continue;
      const double added = (ratio - 1.0) * source.model(c, c) / scatter.variance(c) * before;
      variance(c) += added;
      const double after = bounded(c, before + added);
      if (after >= kReportedSigmaFactor * kReportedSigmaFactor * before) {
        found.push_back({source.name, c, std::sqrt(ratio), std::sqrt(after / before)});
      }
    }
  }
  BlockCovariance out = covariance;
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(n);
  for (int c = 0; c < n; ++c) {
    const double before = covariance.matrix(c, c);
    if (before > 0.0) scale(c) = std::sqrt(bounded(c, variance(c)) / before);
  }
  out.matrix = scale.asDiagonal() * covariance.matrix * scale.asDiagonal();
  out.ok = out.matrix.allFinite();
  std::stable_sort(found.begin(), found.end(), [](const ScatterExcess& a, const ScatterExcess& b) {
    return a.sigma_factor > b.sigma_factor;
  });
  if (excess != nullptr) *excess = std::move(found);
  return out;
}

}  // namespace estimation
}  // namespace autocal
