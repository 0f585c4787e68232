#include "autocal/factors/loss.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace factors {

namespace {

std::string Trim(const std::string& s) {
  const auto not_space = [](unsigned char c) { return !std::isspace(c); };
  const auto begin = std::find_if(s.begin(), s.end(), not_space);
  const auto end = std::find_if(s.rbegin(), s.rend(), not_space).base();
  return begin < end ? std::string(begin, end) : std::string();
}

// A scale is in sigmas. Outside [kMinLossScale, kMaxLossScale] Ceres' losses break down:
// Cauchy keeps b = scale^2 and c = 1 / b, so a scale of 1e300 evaluates rho = inf * 0 = NaN,
// and a scale below 1e-154 makes b zero. Within it, rho stays finite for any finite residual.
void CheckScale(double scale, const std::string& context) {
  if (!(scale >= kMinLossScale && scale <= kMaxLossScale)) {
    std::ostringstream message;
    message << "robust loss '" << context << "': scale must be between " << kMinLossScale << " and "
            << kMaxLossScale << " sigmas, got " << scale << " (for no robust loss write none)";
    throw Error(message.str());
  }
}

}  // namespace

LossOptions ParseLossOptions(const std::string& text) {
  const std::string trimmed = Trim(text);
  const size_t split = trimmed.find_first_of(": \t");
  LossOptions options;
  options.type = ParseRobustLoss(trimmed.substr(0, split));
  if (split == std::string::npos) return options;
  const std::string scale_text = Trim(trimmed.substr(split + 1));
  char* end = nullptr;
  const double scale = std::strtod(scale_text.c_str(), &end);
  if (scale_text.empty() || end != scale_text.c_str() + scale_text.size()) {
    throw Error("robust loss '" + text + "': expected a number after the type, found '" +
                scale_text + "'");
  }
  CheckScale(scale, text);
  options.scale = scale;
  return options;
}

ceres::LossFunction* MakeLossFunction(const LossOptions& options) {
  CheckScale(options.scale, RobustLossName(options.type));
  switch (options.type) {
    case RobustLoss::kNone:
      return nullptr;
    case RobustLoss::kHuber:
      return new ceres::HuberLoss(options.scale);
    case RobustLoss::kCauchy:
      return new ceres::CauchyLoss(options.scale);
  }
  return nullptr;
}

void SandwichRatio::Add(double r) {
  ++count_;
  if (loss_ == nullptr) return;
  const double s = r * r;
  double rho[3];
  loss_->Evaluate(s, rho);
  weight_ += s > 0.0 ? rho[1] * rho[1] * s / rho[0] : 1.0;
  psi_squared_ += rho[1] * rho[1] * s;
  psi_slope_ += rho[1] + 2.0 * s * rho[2];  // d/dr (rho'(r^2) r)
}

RowPull SandwichRatio::pull() const {
  if (loss_ == nullptr) return {static_cast<double>(count_), static_cast<double>(count_)};
  return {psi_squared_, weight_};
}

RowPull ExpectedRowPull(const ceres::LossFunction* loss, int dimension) {
  if (dimension < 1) {
    throw Error("ExpectedRowPull: a residual block has at least one row, got " +
                std::to_string(dimension));
  }
  const double k = static_cast<double>(dimension);
  if (loss == nullptr) return {k, k};
  // Over t = |r|, chi-distributed with k degrees of freedom: density
  // t^(k-1) exp(-t^2 / 2) / (2^(k/2-1) Gamma(k/2)), by Simpson's rule on [0, sqrt(k) + 12],
  // beyond which the density is below 1e-30.
  constexpr int kIntervals = 4000;
  const double end = std::sqrt(k) + 12.0;
  const double h = end / kIntervals;
  const double log_norm = (0.5 * k - 1.0) * std::log(2.0) + std::lgamma(0.5 * k);
  RowPull out{0.0, 0.0};
  for (int i = 0; i <= kIntervals; ++i) {
    const double t = h * i;
    const double simpson = (i == 0 || i == kIntervals) ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
    const double density = t > 0.0 ? std::exp((k - 1.0) * std::log(t) - 0.5 * t * t - log_norm)
                                   : (k == 1.0 ? std::exp(-log_norm) : 0.0);
    double rho[3];
    loss->Evaluate(t * t, rho);
    out.pull_squared += simpson * density * rho[1] * rho[1] * t * t;
    out.weight += simpson * density * k * rho[1];
  }
  out.pull_squared *= h / 3.0;
  out.weight *= h / 3.0;
  return out;
}

double SandwichRatio::kappa() const {
  if (loss_ == nullptr || count_ == 0 || !(psi_slope_ > 0.0)) return 1.0;
  const double n = static_cast<double>(count_);
  return (weight_ / n) * (psi_squared_ / n) / ((psi_slope_ / n) * (psi_slope_ / n));
}

bool DownweightedByLoss(const ceres::LossFunction* loss, double s) {
  if (loss == nullptr) return false;
  double rho[3];
  loss->Evaluate(s, rho);
  return rho[1] < 0.5;
}

}  // namespace factors
}  // namespace autocal
