#include "estimation/lower_gram.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <random>
#include <vector>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace internal {
namespace {

struct Tall {
  Eigen::MatrixXd J;  // column-major
  Eigen::VectorXd r;
};

Tall RandomTall(int n, int c, std::mt19937* rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  Tall t{Eigen::MatrixXd(n, c), Eigen::VectorXd(n)};
  for (int j = 0; j < c; ++j) {
    for (int i = 0; i < n; ++i) t.J(i, j) = normal(*rng) * (1.0 + j);
  }
  for (int i = 0; i < n; ++i) t.r(i) = normal(*rng);
  return t;
}

// The documented order: lane i mod 4 over the rows below the last multiple of four, the lanes
// paired, then the remaining rows.
double OrderedDot(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  const Eigen::Index n = a.size(), n4 = n - n % 4;
  double lane[4] = {0.0, 0.0, 0.0, 0.0};
  for (Eigen::Index i = 0; i < n4; ++i) lane[i % 4] += a(i) * b(i);
  double s = (lane[0] + lane[1]) + (lane[2] + lane[3]);
  for (Eigen::Index i = n4; i < n; ++i) s += a(i) * b(i);
  return s;
}

TEST(LowerGramAndGradient, IsJtJAndJtrInTheDocumentedOrderOnEitherPath) {
  std::mt19937 rng(3);
  for (int n : {0, 1, 3, 4, 7, 29, 256, 2001}) {
    for (int c : {1, 3, 5, 22, kMaxLowerGramColumns}) {
      const Tall t = RandomTall(n, c, &rng);
      for (bool simd : {true, false}) {
        Eigen::MatrixXd gram = Eigen::MatrixXd::Constant(c, c, -7.0);
        Eigen::VectorXd gradient(c);
        LowerGramAndGradient(t.J.data(), n, c, t.r.data(), gram.data(), gradient.data(), simd);
        for (int a = 0; a < c; ++a) {
          for (int b = 0; b < c; ++b) {
            if (b > a) {
              EXPECT_EQ(gram(a, b), -7.0) << "the strictly upper triangle is not written";
            } else {
              EXPECT_EQ(gram(a, b), OrderedDot(t.J.col(a), t.J.col(b)))
                  << "n " << n << " c " << c << " (" << a << ", " << b << ") simd " << simd;
            }
          }
          EXPECT_EQ(gradient(a), OrderedDot(t.J.col(a), t.r)) << "n " << n << " c " << c;
        }
        const Eigen::MatrixXd reference = t.J.transpose() * t.J;
        const double scale = 1.0 + reference.cwiseAbs().maxCoeff();
        EXPECT_LE((gram.triangularView<Eigen::Lower>().toDenseMatrix() -
                   reference.triangularView<Eigen::Lower>().toDenseMatrix())
                      .cwiseAbs()
                      .maxCoeff(),
                  1e-13 * scale);
      }
    }
  }
}

TEST(LowerGramAndGradient, RefusesUnsupportedSizes) {
  double J[4] = {1.0, 2.0, 3.0, 4.0}, r[4] = {0.0, 0.0, 0.0, 0.0};
  std::vector<double> gram((kMaxLowerGramColumns + 1) * (kMaxLowerGramColumns + 1));
  std::vector<double> gradient(kMaxLowerGramColumns + 1);
  EXPECT_THROW(
      LowerGramAndGradient(J, 1, kMaxLowerGramColumns + 1, r, gram.data(), gradient.data()), Error);
  EXPECT_THROW(LowerGramAndGradient(J, -1, 2, r, gram.data(), gradient.data()), Error);
}

}  // namespace
}  // namespace internal
}  // namespace estimation
}  // namespace autocal
