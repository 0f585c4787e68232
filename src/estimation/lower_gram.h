#pragma once

// J^T J and J^T r of a tall column-major J (n x c, c <= kMaxLowerGramColumns), the inner step
// of a compressed point group's linearization (docs/sliding_window.md, Eq. W3): about 250
// products per point for c = 22, the largest part of the build after the points' own rows.
//
// Every sum runs in one fixed order: row i goes to lane i mod 4, the lanes are summed in rows'
// order, then (lane 0 + lane 1) + (lane 2 + lane 3), then the rows past the last multiple of
// four. With AVX2 the four lanes are one register (chosen at run time); without, plain loops
// add in the same order, so both give the same bits.

namespace autocal {
namespace estimation {
namespace internal {

constexpr int kMaxLowerGramColumns = 32;

// gram (c x c, column-major): its lower triangle, diagonal included, set to that of J^T J
// (the strictly upper one untouched); gradient (c): J^T r. Rows n >= 0. `simd` false takes
// the plain loops even where AVX2 is available (the same bits; for tests). Throws
// autocal::Error for c outside [0, kMaxLowerGramColumns] or n < 0.
void LowerGramAndGradient(const double* J, int n, int c, const double* r, double* gram,
                          double* gradient, bool simd = true);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
