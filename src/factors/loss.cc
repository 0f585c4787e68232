#include "autocal/factors/loss.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>

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

void CheckScale(double scale, const std::string& context) {
  if (!(scale > 0.0) || !std::isfinite(scale)) {
    throw Error("robust loss '" + context + "': scale must be a positive number, got " +
                std::to_string(scale));
  }
}

}  // namespace

LossType ParseLossType(const std::string& name) {
  std::string lower = Trim(name);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (lower == "none") return LossType::kNone;
  if (lower == "huber") return LossType::kHuber;
  if (lower == "cauchy") return LossType::kCauchy;
  throw Error("unknown robust loss '" + name + "' (expected none, huber or cauchy)");
}

const char* LossTypeName(LossType type) {
  switch (type) {
    case LossType::kNone:
      return "none";
    case LossType::kHuber:
      return "huber";
    case LossType::kCauchy:
      return "cauchy";
  }
  return "none";
}

LossOptions ParseLossOptions(const std::string& text) {
  const std::string trimmed = Trim(text);
  const size_t split = trimmed.find_first_of(": \t");
  LossOptions options;
  options.type = ParseLossType(trimmed.substr(0, split));
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
  CheckScale(options.scale, LossTypeName(options.type));
  switch (options.type) {
    case LossType::kNone:
      return nullptr;
    case LossType::kHuber:
      return new ceres::HuberLoss(options.scale);
    case LossType::kCauchy:
      return new ceres::CauchyLoss(options.scale);
  }
  return nullptr;
}

}  // namespace factors
}  // namespace autocal
