#pragma once

// Angle unit constants, defined once for the whole library. kPi equals M_PI to the last bit;
// conversions multiply by the factor, x_deg = kRadToDeg * x_rad.

namespace autocal {

constexpr double kPi = 3.14159265358979323846;
constexpr double kRadToDeg = 180.0 / kPi;
constexpr double kDegToRad = kPi / 180.0;

}  // namespace autocal
