#include "estimation/inertial_fit.h"

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>

#include "autocal/common/error.h"
#include "autocal/sensors/imu_preintegration.h"

namespace autocal {
namespace estimation {
namespace internal {

InertialFit::InertialFit(const sensors::ImuSamples& imu, const std::vector<KeyframeSlot>& slots,
                         const CalibrationInitializerOptions& options, const Eigen::Matrix3d& R_I_L,
                         const Eigen::Vector3d& b_g, const Eigen::Matrix3d& R_O_I_rest,
                         const Eigen::Vector3d& f_rest, const Eigen::Vector3d& up_I,
                         const StillStart* rest)
    : options_(options), n_(static_cast<int>(slots.size())), dim_(kV + 3 * n_) {
  const Eigen::Matrix3d I3 = Eigen::Matrix3d::Identity();
  // Weak priors on the lever arm and the accelerometer bias, and gravity from the rest
  // period (eq. I3): g_O = -R_O_I,rest (f_rest - b_a).
  rows_.push_back({{{kP, I3}}, options.p_I_L_prior, options.p_I_L_prior_sigma_m});
  rows_.push_back({{{kBa, I3}}, Eigen::Vector3d::Zero(), options.accel_bias_prior_sigma_m_s2});
  // Theta = 0 (one row of three): without horizontal acceleration its column is zero.
  rows_.push_back({{{kTheta, Eigen::Vector3d::UnitX()}},
                   Eigen::Vector3d::Zero(),
                   options.vertical_rotation_prior_sigma_rad});
  rows_.push_back(
      {{{kG, I3}, {kBa, -R_O_I_rest}}, -(R_O_I_rest * f_rest), options.gravity_prior_sigma_m_s2});
  sensors::PreintegrationOptions preintegration_options;
  for (const KeyframeSlot& slot : slots) R_.push_back(slot.T_O_L.R() * R_I_L.transpose());
  p_O_I_0_ = slots.front().T_O_L.p;
  for (int i = 0; i + 1 < n_; ++i) {
    const KeyframeSlot& si = slots[static_cast<size_t>(i)];
    const KeyframeSlot& sj = slots[static_cast<size_t>(i + 1)];
    const Eigen::Matrix3d& Ri = R_[static_cast<size_t>(i)];
    const Eigen::Matrix3d& Rj = R_[static_cast<size_t>(i + 1)];
    sensors::ImuPreintegration pre(options.imu_noise, preintegration_options, b_g,
                                   Eigen::Vector3d::Zero());
    pre.Integrate(imu, si.t_ns, sj.t_ns);
    const double dt = pre.dt_s();
    deltas_.push_back({dt, pre.delta_p(), pre.d_p_d_ba()});
    const sensors::Matrix15d cov = pre.Covariance();
    // Odometry tilt errors rotate the gravity-compensating part of dv and dp.
    const double tilt_v =
        options.odometry_rotation_sigma_rad * preintegration_options.gravity_m_s2 * dt;
    const double sigma_v = std::sqrt(cov.block<3, 3>(3, 3).trace() / 3.0 + tilt_v * tilt_v);
    const double sigma_p =
        std::sqrt(2.0 * options.odometry_position_sigma_m * options.odometry_position_sigma_m +
                  cov.block<3, 3>(6, 6).trace() / 3.0 + 0.25 * dt * dt * tilt_v * tilt_v);
    // Eq. I5: p_j - p_i - v_i dt - g_O dt^2/2 - R_i (dp + J_p b_a) = 0.
    position_rows_.push_back(rows_.size());
    rows_.push_back({{{kP, -(Rj - Ri)},
                      {kBa, -Ri * pre.d_p_d_ba()},
                      {kG, -0.5 * dt * dt * I3},
                      {kTheta, Ri * up_I.cross(pre.delta_p())},
                      {VelocityIndex(i), -dt * I3}},
                     Ri * pre.delta_p() - (sj.T_O_L.p - si.T_O_L.p),
                     sigma_p});
    // Eq. I6: v_j - v_i - g_O dt - R_i (dv + J_v b_a) = 0.
    rows_.push_back({{{kBa, -Ri * pre.d_v_d_ba()},
                      {kG, -dt * I3},
                      {kTheta, Ri * up_I.cross(pre.delta_v())},
                      {VelocityIndex(i), -I3},
                      {VelocityIndex(i + 1), I3}},
                     Ri * pre.delta_v(),
                     sigma_v});
  }
  // Zero-velocity rows (eq. I4) for keyframes inside a true rest period: they anchor the IMU's
  // velocity chain, so that an odometry slip cannot shift it and shows as an outlier.
  if (rest) {
    for (int k = 0; k < n_; ++k) {
      const int64_t t_ns = slots[static_cast<size_t>(k)].t_ns;
      if (t_ns < rest->t_begin_ns || t_ns > rest->t_end_ns) continue;
      rows_.push_back(
          {{{VelocityIndex(k), I3}}, Eigen::Vector3d::Zero(), options.rest_velocity_sigma_m_s});
    }
  }
  weights_.assign(rows_.size(), 1.0);
}

void InertialFit::Solve(InertialAlignment* fit, std::vector<Eigen::Vector3d>* p_O_I,
                        std::vector<Eigen::Vector3d>* v_O_I) {
  // Huber re-weighting of the odometry positions with every lever-arm axis free.
  const Eigen::Matrix<bool, 3, 1> all_free = Eigen::Matrix<bool, 3, 1>::Constant(false);
  Eigen::VectorXd x;
  for (int iteration = 0; iteration < options_.robust_iterations; ++iteration) {
    x = SolveHolding(all_free, false);
    for (size_t r : position_rows_) {
      const double normalized = Residual(rows_[r], x).norm() / rows_[r].sigma;
      weights_[r] = normalized <= options_.huber_sigmas ? 1.0 : options_.huber_sigmas / normalized;
    }
  }
  x = SolveHolding(all_free, false);
  // Which lever-arm axes the data determines: posterior standard deviations with only the
  // weak prior, inflated by the variance factor of the position residuals when it exceeds 1
  // (odometry noisier than odometry_position_sigma_m). A factor below 1 is not applied: the
  // residuals are small because each keyframe's free velocity absorbs them (the count below
  // does not subtract those unknowns), not because the lever arm is known. Applied, it made
  // the 60 s urban logs' sigma 1-2 cm where x, y were 3-25 cm off (docs/initialization.md).
  double chi2 = 0.0, sum_sq = 0.0, weight_sum = 0.0;
  for (size_t r : position_rows_) {
    const Eigen::Vector3d e = Residual(rows_[r], x);
    chi2 += weights_[r] * e.squaredNorm() / (rows_[r].sigma * rows_[r].sigma);
    sum_sq += weights_[r] * e.squaredNorm();
    weight_sum += weights_[r];
  }
  const double variance_factor = std::max(1.0, chi2 / std::max(1.0, 3.0 * weight_sum));
  fit->position_rms_m = std::sqrt(sum_sq / std::max(1.0, 3.0 * weight_sum));
  Eigen::SparseMatrix<double> H;
  Eigen::VectorXd g;
  Build(AllFree(), x, dim_, &H, &g);
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(H);
  if (solver.info() != Eigen::Success) throw Error("inertial alignment: singular normal equations");
  const Eigen::MatrixXd covariance =
      variance_factor *
      Eigen::MatrixXd(solver.solve(Eigen::MatrixXd::Identity(dim_, kV))).topRows<kV>();
  for (int axis = 0; axis < 3; ++axis) {
    fit->lever_arm_std_m(axis) = std::sqrt(std::max(0.0, covariance(kP + axis, kP + axis)));
    fit->excited(axis) = fit->lever_arm_std_m(axis) < options_.max_excited_lever_arm_std_m;
  }
  // Theta likewise: a straight drive at steady speed leaves it to noise (held at zero).
  fit->vertical_rotation_std_rad = std::sqrt(std::max(0.0, covariance(kTheta, kTheta)));
  fit->vertical_rotation_determined =
      fit->vertical_rotation_std_rad < options_.max_vertical_rotation_std_rad;
  x = SolveHolding(fit->excited.unaryExpr([](bool e) { return !e; }),
                   !fit->vertical_rotation_determined);
  fit->p_I_L = x.segment<3>(kP);
  fit->accel_bias_m_s2 = x.segment<3>(kBa);
  fit->gravity_O_m_s2 = x.segment<3>(kG);
  fit->vertical_rotation_rad = x(kTheta);
  fit->downweighted_positions = 0;
  for (size_t r : position_rows_) fit->downweighted_positions += weights_[r] < 1.0 ? 1 : 0;

  // Eq. I7: p_k+1 = p_k + v_k dt + g_O dt^2/2 + R_k (dp + J_p b_a), from p_0 = p_O_L,0 - R_0 p_I_L.
  v_O_I->resize(static_cast<size_t>(n_));
  for (int k = 0; k < n_; ++k) (*v_O_I)[static_cast<size_t>(k)] = x.segment<3>(VelocityIndex(k));
  p_O_I->assign(1, p_O_I_0_ - R_.front() * fit->p_I_L);
  for (size_t k = 0; k < deltas_.size(); ++k) {
    const Delta& d = deltas_[k];
    p_O_I->push_back(p_O_I->back() + (*v_O_I)[k] * d.dt_s +
                     0.5 * d.dt_s * d.dt_s * fit->gravity_O_m_s2 +
                     R_[k] * (d.dp + d.d_p_d_ba * fit->accel_bias_m_s2));
  }
}

Eigen::Vector3d InertialFit::Residual(const Row& row, const Eigen::VectorXd& x) {
  Eigen::Vector3d r = -row.b;
  for (const auto& [c, A] : row.blocks) r += A * x.segment(c, A.cols());
  return r;
}

// The normal equations over the columns `index` maps to (index[c] < 0: column c is held
// at held_x(c) and moves to the right-hand side). H is sparse: each keyframe's velocity
// couples only to its neighbours' and to the 10 shared unknowns.
void InertialFit::Build(const std::vector<int>& index, const Eigen::VectorXd& held_x, int size,
                        Eigen::SparseMatrix<double>* H, Eigen::VectorXd* g) const {
  std::vector<Eigen::Triplet<double>> triplets;
  *g = Eigen::VectorXd::Zero(size);
  for (size_t r = 0; r < rows_.size(); ++r) {
    const Row& row = rows_[r];
    const double w = weights_[r] / (row.sigma * row.sigma);
    Eigen::Vector3d b = row.b;
    for (const auto& [c, A] : row.blocks) {
      for (Eigen::Index k = 0; k < A.cols(); ++k) {
        if (index[static_cast<size_t>(c + k)] < 0) b -= A.col(k) * held_x(c + k);
      }
    }
    for (const auto& [ci, Ai] : row.blocks) {
      for (Eigen::Index ki = 0; ki < Ai.cols(); ++ki) {
        const int i = index[static_cast<size_t>(ci + ki)];
        if (i < 0) continue;
        (*g)(i) += w * Ai.col(ki).dot(b);
        for (const auto& [cj, Aj] : row.blocks) {
          for (Eigen::Index kj = 0; kj < Aj.cols(); ++kj) {
            const int j = index[static_cast<size_t>(cj + kj)];
            if (j >= 0) triplets.emplace_back(i, j, w * Ai.col(ki).dot(Aj.col(kj)));
          }
        }
      }
    }
  }
  H->resize(size, size);
  H->setFromTriplets(triplets.begin(), triplets.end());
}

// Every column free.
std::vector<int> InertialFit::AllFree() const {
  std::vector<int> index(static_cast<size_t>(dim_));
  for (int c = 0; c < dim_; ++c) index[static_cast<size_t>(c)] = c;
  return index;
}

// Solves with the lever-arm axes flagged in `hold` fixed at the prior and, with hold_theta,
// theta at zero (their columns move to the right-hand side).
Eigen::VectorXd InertialFit::SolveHolding(const Eigen::Matrix<bool, 3, 1>& hold,
                                          bool hold_theta) const {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(dim_);
  std::vector<int> index(static_cast<size_t>(dim_));
  int size = 0;
  for (int c = 0; c < dim_; ++c) {
    const bool held_lever_arm = c < kBa && hold(c);
    const bool held = held_lever_arm || (c == kTheta && hold_theta);
    if (held_lever_arm) x(c) = options_.p_I_L_prior(c);
    index[static_cast<size_t>(c)] = held ? -1 : size++;
  }
  Eigen::SparseMatrix<double> H;
  Eigen::VectorXd g;
  Build(index, x, size, &H, &g);
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(H);
  if (solver.info() != Eigen::Success) throw Error("inertial alignment: singular normal equations");
  const Eigen::VectorXd x_free = solver.solve(g);
  for (int c = 0; c < dim_; ++c) {
    if (index[static_cast<size_t>(c)] >= 0) x(c) = x_free(index[static_cast<size_t>(c)]);
  }
  return x;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
