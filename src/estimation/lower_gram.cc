#include "estimation/lower_gram.h"

#include <array>
#include <cstddef>
#include <string>

#include "autocal/common/error.h"
#include "common/cpu_features.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define AUTOCAL_LOWER_GRAM_AVX2 1
#endif

namespace autocal {
namespace estimation {
namespace internal {
namespace {

// Lane l of sums[p] is the sum over rows i < n4, i = l mod 4, of a_i b_i for the p-th pair
// (a, b) in the order (0, 0), (1, 0), (1, 1), (2, 0), ..., each column a followed by the pair
// (a, r) in gradient_sums[a].
using Lanes = std::array<double, 4>;

void LaneSumsPlain(const double* J, int n, int n4, int c, const double* r, Lanes* sums,
                   Lanes* gradient_sums) {
  int p = 0;
  for (int a = 0; a < c; ++a) {
    const double* column_a = J + static_cast<size_t>(a) * static_cast<size_t>(n);
    for (int b = 0; b <= a + 1; ++b) {
      const double* other = b <= a ? J + static_cast<size_t>(b) * static_cast<size_t>(n) : r;
      Lanes s = {0.0, 0.0, 0.0, 0.0};
      for (int i = 0; i < n4; i += 4) {
        for (int l = 0; l < 4; ++l) s[static_cast<size_t>(l)] += column_a[i + l] * other[i + l];
      }
      if (b <= a) {
        sums[p++] = s;
      } else {
        gradient_sums[a] = s;
      }
    }
  }
}

#ifdef AUTOCAL_LOWER_GRAM_AVX2
// The same sums, four pairs (a, b .. b + 3) at a time sharing the loads of column a.
__attribute__((target("avx2"))) void LaneSumsAvx2(const double* J, int n, int n4, int c,
                                                  const double* r, Lanes* sums,
                                                  Lanes* gradient_sums) {
  const size_t stride = static_cast<size_t>(n);
  int p = 0;
  for (int a = 0; a < c; ++a) {
    const double* column_a = J + static_cast<size_t>(a) * stride;
    int b = 0;
    for (; b + 3 <= a; b += 4, p += 4) {
      const double* b0 = J + static_cast<size_t>(b) * stride;
      const double* b1 = b0 + stride;
      const double* b2 = b1 + stride;
      const double* b3 = b2 + stride;
      __m256d s0 = _mm256_setzero_pd(), s1 = s0, s2 = s0, s3 = s0;
      for (int i = 0; i < n4; i += 4) {
        const __m256d x = _mm256_loadu_pd(column_a + i);
        s0 = _mm256_add_pd(s0, _mm256_mul_pd(x, _mm256_loadu_pd(b0 + i)));
        s1 = _mm256_add_pd(s1, _mm256_mul_pd(x, _mm256_loadu_pd(b1 + i)));
        s2 = _mm256_add_pd(s2, _mm256_mul_pd(x, _mm256_loadu_pd(b2 + i)));
        s3 = _mm256_add_pd(s3, _mm256_mul_pd(x, _mm256_loadu_pd(b3 + i)));
      }
      _mm256_storeu_pd(sums[p].data(), s0);
      _mm256_storeu_pd(sums[p + 1].data(), s1);
      _mm256_storeu_pd(sums[p + 2].data(), s2);
      _mm256_storeu_pd(sums[p + 3].data(), s3);
    }
    for (; b <= a + 1; ++b) {
      const double* other = b <= a ? J + static_cast<size_t>(b) * stride : r;
      __m256d s = _mm256_setzero_pd();
      for (int i = 0; i < n4; i += 4) {
        s = _mm256_add_pd(s,
                          _mm256_mul_pd(_mm256_loadu_pd(column_a + i), _mm256_loadu_pd(other + i)));
      }
      _mm256_storeu_pd(b <= a ? sums[p++].data() : gradient_sums[a].data(), s);
    }
  }
}

#endif

double Total(const Lanes& s) { return (s[0] + s[1]) + (s[2] + s[3]); }

}  // namespace

void LowerGramAndGradient(const double* J, int n, int c, const double* r, double* gram,
                          double* gradient, bool simd) {
  if (c < 0 || c > kMaxLowerGramColumns || n < 0) {
    throw Error("LowerGramAndGradient: " + std::to_string(n) + " x " + std::to_string(c) +
                " is not a supported size");
  }
  std::array<Lanes, kMaxLowerGramColumns*(kMaxLowerGramColumns + 1) / 2> sums;
  std::array<Lanes, kMaxLowerGramColumns> gradient_sums;
  const int n4 = n - n % 4;
#ifdef AUTOCAL_LOWER_GRAM_AVX2
  if (simd && autocal::internal::CpuHasAvx2()) {
    LaneSumsAvx2(J, n, n4, c, r, sums.data(), gradient_sums.data());
  } else {
    LaneSumsPlain(J, n, n4, c, r, sums.data(), gradient_sums.data());
  }
#else
  static_cast<void>(simd);
  LaneSumsPlain(J, n, n4, c, r, sums.data(), gradient_sums.data());
#endif
  const size_t stride = static_cast<size_t>(n);
  size_t p = 0;
  for (int a = 0; a < c; ++a) {
    const double* column_a = J + static_cast<size_t>(a) * stride;
    for (int b = 0; b <= a; ++b) {
      const double* column_b = J + static_cast<size_t>(b) * stride;
      double s = Total(sums[p++]);
      for (int i = n4; i < n; ++i) s += column_a[i] * column_b[i];
      gram[static_cast<size_t>(a) + static_cast<size_t>(b) * static_cast<size_t>(c)] = s;
    }
    double s = Total(gradient_sums[static_cast<size_t>(a)]);
    for (int i = n4; i < n; ++i) s += column_a[i] * r[i];
    gradient[a] = s;
  }
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
