#pragma once

// Number formatting shared by the reports and messages.

#include <cstdio>
#include <string>

namespace autocal {

// `value` with exactly `decimals` digits after the point ("%.*f").
inline std::string FormatFixed(double value, int decimals) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  return buffer;
}

}  // namespace autocal
