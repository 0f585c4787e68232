#pragma once

// Robust loss per factor type (docs/factors.md, "Robust losses"). Residuals are whitened,
// so a scale is in standard deviations: Huber with scale 1.5 is quadratic up to 1.5 sigma.

#include <ceres/loss_function.h>

#include <string>

namespace autocal {
namespace factors {

enum class LossType { kNone, kHuber, kCauchy };

struct LossOptions {
  LossType type = LossType::kNone;
  double scale = 1.0;  // > 0, in whitened units (sigmas)
};

// Per sensor, as a problem file chooses them. Defaults: the IMU and priors are trusted
// (quadratic); wheel slip, GNSS multipath and LiDAR mis-associations are outliers.
struct FactorLossOptions {
  LossOptions imu;
  LossOptions prior;
  LossOptions wheel{LossType::kHuber, 2.0};
  LossOptions gnss{LossType::kCauchy, 3.0};
  LossOptions lidar{LossType::kHuber, 1.0};
};

// "none", "huber" or "cauchy" (case-insensitive); throws autocal::Error naming the
// accepted values otherwise.
LossType ParseLossType(const std::string& name);
const char* LossTypeName(LossType type);

// "none", "<type>" (scale 1) or "<type>:<scale>" / "<type> <scale>", e.g. "huber:1.5".
// Throws autocal::Error on an unknown type or a scale that is not a positive number.
LossOptions ParseLossOptions(const std::string& text);

// A new loss function for Problem::AddResidualBlock (which takes ownership), or nullptr for
// kNone (plain least squares). Throws autocal::Error on a non-positive scale.
ceres::LossFunction* MakeLossFunction(const LossOptions& options);

}  // namespace factors
}  // namespace autocal
