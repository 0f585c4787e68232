#include "estimation/residual_curvature.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace estimation {
namespace internal {
namespace {

// The shape of an IMU factor's velocity rows: r = R(q)^T (v_j - v_i - g) - m, with the
// attitude q (right-perturbed) turning the velocity change. Its second derivative in q is
// what Gauss-Newton drops.
struct VelocityRows {
  Eigen::Vector3d measured;
  template <typename T>
  bool operator()(const T* q_ptr, const T* v_i_ptr, const T* v_j_ptr, T* r_ptr) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(q_ptr);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> v_i(v_i_ptr), v_j(v_j_ptr);
    const Eigen::Matrix<T, 3, 1> g(T(0), T(0), T(-9.8));
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(r_ptr);
    r = q.conjugate() * (v_j - v_i - g) - measured.cast<T>();
    r *= T(4.0);  // whitened
    return true;
  }
};

struct Fixture {
  Eigen::Quaterniond q;
  Eigen::Vector3d v_i, v_j;
  ceres::Problem::Options options;
  std::unique_ptr<ceres::Problem> problem;
  geometry::RightQuaternionManifold quaternion;
  ceres::ResidualBlockId id = nullptr;

  explicit Fixture(uint32_t seed, ceres::LossFunction* loss = nullptr) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, 1.0);
    auto vec = [&] { return Eigen::Vector3d(n(rng), n(rng), n(rng)); };
    q = Eigen::Quaterniond(geometry::Exp(Eigen::Vector3d(vec())));
    v_i = 3.0 * vec();
    v_j = v_i + vec();
    VelocityRows rows;
    // The measurement misses the states by a few tenths: a residual for r d2r to act on.
    rows.measured = q.conjugate() * (v_j - v_i - Eigen::Vector3d(0, 0, -9.8)) + 0.3 * vec();
    options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem = std::make_unique<ceres::Problem>(options);
    problem->AddParameterBlock(q.coeffs().data(), 4, &quaternion);
    id = problem->AddResidualBlock(
        new ceres::AutoDiffCostFunction<VelocityRows, 3, 4, 3, 3>(new VelocityRows(rows)), loss,
        q.coeffs().data(), v_i.data(), v_j.data());
  }

  // 1/2 rho(|r|^2) at (q Exp(d[0:3]), v_i + d[3:6], v_j + d[6:9]).
  double CostAt(const Eigen::Matrix<double, 9, 1>& d) {
    const Eigen::Quaterniond q0 = q;
    const Eigen::Vector3d vi0 = v_i, vj0 = v_j;
    q = q0 * geometry::Exp(Eigen::Vector3d(d.head<3>()));
    v_i = vi0 + d.segment<3>(3);
    v_j = vj0 + d.tail<3>();
    double cost = 0.0;
    problem->EvaluateResidualBlock(id, true, &cost, nullptr, nullptr);
    q = q0;
    v_i = vi0;
    v_j = vj0;
    return cost;
  }
};

// The residual (no loss) and its tangent Jacobian, 3 columns for q.
struct Linearization {
  Eigen::Vector3d r;
  Eigen::Matrix<double, 3, 9> J;
};
Linearization Linearize(Fixture* f) {
  Linearization out;
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> j_q, j_i, j_j;
  double* jacobians[] = {j_q.data(), j_i.data(), j_j.data()};
  double cost = 0.0;
  EXPECT_TRUE(f->problem->EvaluateResidualBlock(f->id, false, &cost, out.r.data(), jacobians));
  out.J << j_q, j_i, j_j;
  return out;
}

// Offsets of the three blocks in a 9-column tangent vector.
BlockOffsets OffsetsOf(Fixture* f) {
  return {{f->q.coeffs().data(), 0}, {f->v_i.data(), 3}, {f->v_j.data(), 6}};
}

Eigen::Matrix<double, 9, 9> Dense(const std::vector<Eigen::Triplet<double>>& lower) {
  Eigen::Matrix<double, 9, 9> out = Eigen::Matrix<double, 9, 9>::Zero();
  for (const auto& t : lower) {
    EXPECT_GE(t.row(), t.col());
    out(t.row(), t.col()) += t.value();
    if (t.row() != t.col()) out(t.col(), t.row()) += t.value();
  }
  return out;
}

// The exact Hessian of rho(|r|^2) / 2 in the chart, from second differences of the cost.
Eigen::Matrix<double, 9, 9> NumericHessian(Fixture* f) {
  const double h = 1e-4;
  Eigen::Matrix<double, 9, 9> numeric;
  for (int k = 0; k < 9; ++k) {
    for (int l = 0; l < 9; ++l) {
      Eigen::Matrix<double, 9, 1> ek = Eigen::Matrix<double, 9, 1>::Zero(), el = ek;
      ek(k) = h;
      el(l) = h;
      numeric(k, l) =
          (f->CostAt(ek + el) - f->CostAt(ek - el) - f->CostAt(el - ek) + f->CostAt(-ek - el)) /
          (4.0 * h * h);
    }
  }
  return numeric;
}

// J^T J + sum r d2r is the cost's own Hessian in the chart x (+) delta: second differences of
// the cost agree to 1e-5, where J^T J alone is off by more than 1e-2.
TEST(ResidualCurvature, CompletesGaussNewtonToTheCostsHessian) {
  for (uint32_t seed : {1u, 2u, 3u, 4u}) {
    Fixture f(seed);
    const Eigen::Matrix<double, 9, 9> curvature =
        Dense(ResidualCurvature(f.problem.get(), {f.id}, OffsetsOf(&f)));
    const Eigen::Matrix<double, 3, 9> J = Linearize(&f).J;
    const Eigen::Matrix<double, 9, 9> gauss_newton = J.transpose() * J;

    const Eigen::Matrix<double, 9, 9> numeric = NumericHessian(&f);
    const Eigen::Matrix<double, 9, 9> exact = gauss_newton + curvature;
    EXPECT_LT((exact - numeric).norm(), 1e-5 * numeric.norm()) << "seed " << seed << "\nexact\n"
                                                               << exact << "\nnumeric\n"
                                                               << numeric;
    // Gauss-Newton alone misses it by far more than that tolerance.
    EXPECT_GT((gauss_newton - numeric).norm(), 1e-2 * numeric.norm()) << "seed " << seed;
    // The velocities enter linearly: no curvature among them.
    EXPECT_LT((curvature.bottomRightCorner<6, 6>().norm()), 1e-6) << "seed " << seed;
  }
}

// The symmetric part above cancels what the chart's right Jacobian adds to a rotation's
// columns (1/2 e_k x g, antisymmetric), so that test cannot see it: here the columns as the
// differences give them match the cost's Hessian less J^T J by themselves, and without the
// right Jacobian they would miss it by |1/2 [g]x|, far beyond the tolerance.
TEST(ResidualCurvature, TakesTheChartsRightJacobianForARotation) {
  for (uint32_t seed : {1u, 2u, 3u, 4u}) {
    Fixture f(seed);
    const BlockCurvature block = ResidualBlockCurvature(f.problem.get(), f.id, OffsetsOf(&f));
    ASSERT_EQ(block.columns.rows(), 9);
    ASSERT_EQ(block.columns.cols(), 9);
    EXPECT_EQ(block.h_rows, std::vector<int>({0, 1, 2, 3, 4, 5, 6, 7, 8}));
    const Eigen::Matrix<double, 9, 9> columns = block.columns;
    const auto [r, J] = Linearize(&f);
    const Eigen::Matrix<double, 9, 9> numeric = NumericHessian(&f);
    const Eigen::Matrix<double, 9, 9> exact = J.transpose() * J + columns;
    EXPECT_LT((exact - numeric).norm(), 1e-5 * numeric.norm()) << "seed " << seed << "\ncolumns\n"
                                                               << columns << "\nnumeric\n"
                                                               << numeric;
    const Eigen::Vector3d g = (J.transpose() * r).head<3>();
    const double missed = 0.5 * std::sqrt(2.0) * g.norm();  // |1/2 [g]x|, Frobenius
    EXPECT_GT(missed, 1e-2 * numeric.norm()) << "seed " << seed;
  }
}

TEST(ResidualCurvature, LeavesConstantBlocksOutAndRestoresTheValues) {
  Fixture f(5);
  const Eigen::Vector4d q_before = f.q.coeffs();
  const Eigen::Vector3d v_before = f.v_j;
  f.problem->SetParameterBlockConstant(f.v_i.data());
  BlockOffsets offsets = {{f.q.coeffs().data(), 0}, {f.v_j.data(), 6}};
  const std::vector<Eigen::Triplet<double>> entries =
      ResidualCurvature(f.problem.get(), {f.id}, offsets);
  for (const auto& t : entries) {
    EXPECT_FALSE(t.row() >= 3 && t.row() < 6) << t.row();
    EXPECT_FALSE(t.col() >= 3 && t.col() < 6) << t.col();
  }
  EXPECT_EQ(entries.size(), 6u + 9u + 6u);  // q-q and v_j-v_j lower triangles, v_j-q block
  EXPECT_EQ(f.q.coeffs(), q_before);
  EXPECT_EQ(f.v_j, v_before);
}

// Under a robust loss the exact Hessian is rho' (J^T J + sum r d2r) + 2 rho'' J^T r r^T J: the
// term is weighted by rho', and with the loss's own term added back the sum is the cost's
// Hessian (second differences, with the loss applied).
TEST(ResidualCurvature, WeighsTheTermByTheLossSlope) {
  Fixture f(6, new ceres::CauchyLoss(0.5));
  const Eigen::Matrix<double, 9, 9> curvature =
      Dense(ResidualCurvature(f.problem.get(), {f.id}, OffsetsOf(&f)));
  const auto [r, J] = Linearize(&f);
  double rho[3];
  ceres::CauchyLoss(0.5).Evaluate(r.squaredNorm(), rho);
  ASSERT_LT(rho[1], 0.5);  // well into the loss: the weight matters
  const Eigen::Matrix<double, 9, 1> g = J.transpose() * r;
  const Eigen::Matrix<double, 9, 9> exact =
      rho[1] * J.transpose() * J + curvature + 2.0 * rho[2] * g * g.transpose();
  const Eigen::Matrix<double, 9, 9> numeric = NumericHessian(&f);
  // (The loss's logarithm leaves the second differences a truncation error of a few 1e-5.)
  EXPECT_LT((exact - numeric).norm(), 1e-4 * numeric.norm()) << exact << "\n\n" << numeric;
  // Without the weight (rho' = 1 on the term) it would miss by far more.
  EXPECT_GT(((1.0 / rho[1] - 1.0) * curvature).norm(), 1e-2 * numeric.norm());
}

TEST(ResidualCurvature, RefusesAnotherRotationManifold) {
  Fixture f(7);
  Eigen::Quaterniond other = Eigen::Quaterniond::Identity();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  ceres::EigenQuaternionManifold eigen_quaternion;
  f.problem->AddParameterBlock(other.coeffs().data(), 4, &eigen_quaternion);
  ceres::ResidualBlockId unsupported =
      f.problem->AddResidualBlock(new ceres::AutoDiffCostFunction<VelocityRows, 3, 4, 3, 3>(
                                      new VelocityRows{Eigen::Vector3d::Ones()}),
                                  nullptr, other.coeffs().data(), f.v_i.data(), b.data());
  BlockOffsets offsets = OffsetsOf(&f);
  offsets[other.coeffs().data()] = 9;
  offsets[b.data()] = 12;
  EXPECT_THROW(ResidualCurvature(f.problem.get(), {unsupported}, offsets), Error);
}

}  // namespace
}  // namespace internal
}  // namespace estimation
}  // namespace autocal
