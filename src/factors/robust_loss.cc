#include "autocal/factors/robust_loss.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "autocal/common/error.h"

namespace autocal {
namespace factors {

double RobustKernel::Weight(double residual_m) const {
  const double abs_r = std::abs(residual_m);
  switch (loss) {
    case RobustLoss::kNone:
      return 1.0;
    case RobustLoss::kHuber:
      return abs_r <= scale_m ? 1.0 : scale_m / abs_r;
    case RobustLoss::kCauchy: {
      const double u = residual_m / scale_m;
      return 1.0 / (1.0 + u * u);
    }
  }
  return 1.0;
}

double RobustKernel::Loss(double residual_m) const {
  const double abs_r = std::abs(residual_m);
  switch (loss) {
    case RobustLoss::kNone:
      return 0.5 * residual_m * residual_m;
    case RobustLoss::kHuber:
      return abs_r <= scale_m ? 0.5 * residual_m * residual_m
                              : scale_m * abs_r - 0.5 * scale_m * scale_m;
    case RobustLoss::kCauchy: {
      const double u = residual_m / scale_m;
      return 0.5 * scale_m * scale_m * std::log1p(u * u);
    }
  }
  return 0.0;
}

RobustLoss ParseRobustLoss(const std::string& name) {
  const auto not_space = [](unsigned char c) { return !std::isspace(c); };
  const auto begin = std::find_if(name.begin(), name.end(), not_space);
  const auto end = std::find_if(name.rbegin(), name.rend(), not_space).base();
  std::string lower = begin < end ? std::string(begin, end) : std::string();
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (lower == "none") return RobustLoss::kNone;
  if (lower == "huber") return RobustLoss::kHuber;
  if (lower == "cauchy") return RobustLoss::kCauchy;
  throw Error("unknown robust loss '" + name + "' (expected none, huber or cauchy)");
}

const char* RobustLossName(RobustLoss loss) {
  switch (loss) {
    case RobustLoss::kNone:
      return "none";
    case RobustLoss::kHuber:
      return "huber";
    case RobustLoss::kCauchy:
      return "cauchy";
  }
  return "none";
}

}  // namespace factors
}  // namespace autocal
