#pragma once

// A nonlinear test problem for the estimation module's solvers: a chain of poses with
// relative-pose factors, antenna positions with a shared lever arm (a calibration block,
// Huber loss) and a prior on the first pose, built from noisy measurements of a random truth.

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace test {

struct RelativePoseResidual {
  RelativePoseResidual(const Eigen::Quaterniond& dq, const Eigen::Vector3d& dp)
      : dq_(dq), dp_(dp) {}
  template <typename T>
  bool operator()(const T* qi, const T* pi, const T* qj, const T* pj, T* r) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_i(qi), q_j(qj);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_i(pi), p_j(pj);
    const Eigen::Quaternion<T> error = dq_.cast<T>().conjugate() * q_i.conjugate() * q_j;
    Eigen::Map<Eigen::Matrix<T, 6, 1>> res(r);
    res.template head<3>() = geometry::Log(error) / T(0.01);
    res.template tail<3>() = (q_i.conjugate() * (p_j - p_i) - dp_.cast<T>()) / T(0.05);
    return true;
  }
  Eigen::Quaterniond dq_;
  Eigen::Vector3d dp_;
};

struct AntennaResidual {
  explicit AntennaResidual(const Eigen::Vector3d& z) : z_(z) {}
  template <typename T>
  bool operator()(const T* q, const T* p, const T* lever, T* r) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_W_I(q);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_W_I(p), p_I_A(lever);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> res(r);
    res = (p_W_I + q_W_I * p_I_A - z_.cast<T>()) / T(0.1);
    return true;
  }
  Eigen::Vector3d z_;
};

struct PosePriorResidual {
  PosePriorResidual(const Eigen::Quaterniond& q, const Eigen::Vector3d& p) : q_(q), p_(p) {}
  template <typename T>
  bool operator()(const T* q, const T* p, T* r) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_W_I(q);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_W_I(p);
    Eigen::Map<Eigen::Matrix<T, 6, 1>> res(r);
    res.template head<3>() =
        geometry::Log(Eigen::Quaternion<T>(q_.cast<T>().conjugate() * q_W_I)) / T(0.01);
    res.template tail<3>() = (p_W_I - p_.cast<T>()) / T(0.01);
    return true;
  }
  Eigen::Quaterniond q_;
  Eigen::Vector3d p_;
};

constexpr int kPoses = 6;

struct PoseChain {
  std::array<Eigen::Quaterniond, kPoses> q;
  std::array<Eigen::Vector3d, kPoses> p;
  Eigen::Vector3d lever;
};

// Builds the chain from noisy measurements of a random true trajectory.
class PoseChainProblem {
 public:
  explicit PoseChainProblem(uint32_t seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, 1.0);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    PoseChain truth;
    for (int i = 0; i < kPoses; ++i) {
      truth.q[i] = geometry::Exp(Eigen::Vector3d(0.2 * u(rng), 0.2 * u(rng), 0.7 * i));
      truth.p[i] = Eigen::Vector3d(2.0 * i, std::sin(i), 0.1 * u(rng));
    }
    truth.lever = Eigen::Vector3d(0.8, -0.3, 1.2);
    for (int i = 0; i + 1 < kPoses; ++i) {
      relative_.emplace_back(truth.q[i].conjugate() * truth.q[i + 1] *
                                 geometry::Exp(Eigen::Vector3d(0.01 * noise(rng), 0.01 * noise(rng),
                                                               0.01 * noise(rng))),
                             truth.q[i].conjugate() * (truth.p[i + 1] - truth.p[i]) +
                                 0.05 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
    }
    for (int i = 0; i < kPoses; ++i) {
      antenna_.push_back(truth.p[i] + truth.q[i] * truth.lever +
                         0.1 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
    }
    prior_q_ = truth.q[0];
    prior_p_ = truth.p[0];
    // Initial values: truth perturbed.
    values_ = truth;
    for (int i = 0; i < kPoses; ++i) {
      values_.q[i] =
          truth.q[i] * geometry::Exp(Eigen::Vector3d(0.05 * u(rng), 0.05 * u(rng), 0.05 * u(rng)));
      values_.p[i] += 0.3 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    }
    values_.lever += Eigen::Vector3d(0.2, 0.2, -0.2);
  }

  // Adds pose i's blocks and the factors that arrive with it: its antenna position, the
  // relative pose from pose i - 1 (or the prior for pose 0). As a window would, in turn.
  void AddPose(ceres::Problem* problem, PoseChain* x, int i) const {
    problem->AddParameterBlock(x->q[i].coeffs().data(), 4, new geometry::RightQuaternionManifold);
    problem->AddParameterBlock(x->p[i].data(), 3);
    problem->AddParameterBlock(x->lever.data(), 3);
    if (i == 0) {
      problem->AddResidualBlock(new ceres::AutoDiffCostFunction<PosePriorResidual, 6, 4, 3>(
                                    new PosePriorResidual(prior_q_, prior_p_)),
                                nullptr, x->q[0].coeffs().data(), x->p[0].data());
    } else {
      problem->AddResidualBlock(
          new ceres::AutoDiffCostFunction<RelativePoseResidual, 6, 4, 3, 4, 3>(
              new RelativePoseResidual(relative_[i - 1].first, relative_[i - 1].second)),
          nullptr, x->q[i - 1].coeffs().data(), x->p[i - 1].data(), x->q[i].coeffs().data(),
          x->p[i].data());
    }
    problem->AddResidualBlock(new ceres::AutoDiffCostFunction<AntennaResidual, 3, 4, 3, 3>(
                                  new AntennaResidual(antenna_[i])),
                              new ceres::HuberLoss(0.5), x->q[i].coeffs().data(), x->p[i].data(),
                              x->lever.data());
  }

  // Adds every factor; with `skip_first_pose_factors`, the factors touching pose 0 are left
  // out (they are represented by a marginalization prior instead).
  void Build(ceres::Problem* problem, PoseChain* x, bool skip_first_pose_factors) const {
    for (int i = 0; i < kPoses; ++i) {
      if (skip_first_pose_factors && i == 0) continue;
      problem->AddParameterBlock(x->q[i].coeffs().data(), 4, new geometry::RightQuaternionManifold);
      problem->AddParameterBlock(x->p[i].data(), 3);
    }
    problem->AddParameterBlock(x->lever.data(), 3);
    for (int i = 0; i + 1 < kPoses; ++i) {
      if (skip_first_pose_factors && i == 0) continue;
      problem->AddResidualBlock(
          new ceres::AutoDiffCostFunction<RelativePoseResidual, 6, 4, 3, 4, 3>(
              new RelativePoseResidual(relative_[i].first, relative_[i].second)),
          nullptr, x->q[i].coeffs().data(), x->p[i].data(), x->q[i + 1].coeffs().data(),
          x->p[i + 1].data());
    }
    for (int i = 0; i < kPoses; ++i) {
      if (skip_first_pose_factors && i == 0) continue;
      problem->AddResidualBlock(new ceres::AutoDiffCostFunction<AntennaResidual, 3, 4, 3, 3>(
                                    new AntennaResidual(antenna_[i])),
                                new ceres::HuberLoss(0.5), x->q[i].coeffs().data(), x->p[i].data(),
                                x->lever.data());
    }
    if (!skip_first_pose_factors) {
      problem->AddResidualBlock(new ceres::AutoDiffCostFunction<PosePriorResidual, 6, 4, 3>(
                                    new PosePriorResidual(prior_q_, prior_p_)),
                                nullptr, x->q[0].coeffs().data(), x->p[0].data());
    }
  }

  const PoseChain& initial_values() const { return values_; }

 private:
  std::vector<std::pair<Eigen::Quaterniond, Eigen::Vector3d>> relative_;
  std::vector<Eigen::Vector3d> antenna_;
  Eigen::Quaterniond prior_q_;
  Eigen::Vector3d prior_p_;
  PoseChain values_;
};

inline void SolveTightly(ceres::Problem* problem) {
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 200;
  options.function_tolerance = 1e-16;
  options.gradient_tolerance = 1e-16;
  options.parameter_tolerance = 1e-16;
  ceres::Solver::Summary summary;
  ceres::Solve(options, problem, &summary);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.FullReport();
}

}  // namespace test
}  // namespace autocal
