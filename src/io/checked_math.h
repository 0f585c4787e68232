#pragma once

// Overflow-checked integer arithmetic for the sizes, counts and offsets a reader computes
// from the numbers a file declares: a hostile header must give a clear error, not a
// wrapped size (out-of-bounds reads) or signed overflow (undefined behaviour). Private to
// src/io.

#include <type_traits>

namespace autocal {
namespace io {
namespace internal {

// *sum = a + b; false (and *sum unspecified) when the exact result does not fit in T.
template <typename T>
bool CheckedAdd(T a, T b, T* sum) {
  static_assert(std::is_integral_v<T>, "integers only");
  return !__builtin_add_overflow(a, b, sum);
}

// *product = a * b; false (and *product unspecified) when the exact result does not fit.
template <typename T>
bool CheckedMultiply(T a, T b, T* product) {
  static_assert(std::is_integral_v<T>, "integers only");
  return !__builtin_mul_overflow(a, b, product);
}

}  // namespace internal
}  // namespace io
}  // namespace autocal
