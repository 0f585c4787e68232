#pragma once

// A factor's whitening sigma, checked where the factor is built: a zero, negative or non-finite
// one would make its residuals inf or NaN.

#include <cmath>
#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace factors {
namespace internal {

// Throws autocal::Error "<what> must be finite and > 0, got <sigma>" unless sigma is.
inline void CheckSigma(double sigma, const std::string& what) {
  if (!(sigma > 0.0) || !std::isfinite(sigma)) {
    throw Error(what + " must be finite and > 0, got " + std::to_string(sigma));
  }
}

}  // namespace internal
}  // namespace factors
}  // namespace autocal
