#include "autocal/estimation/gnss_inertial_keyframes.h"

#include <ceres/ceres.h>

#include <cmath>
#include <memory>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/factors/prior_factors.h"
#include "autocal/geometry/manifolds.h"

namespace autocal {
namespace estimation {
namespace {

// The gyro integrated about the vehicle's up axis (R_I_V z, in I) from the first keyframe to
// each keyframe (trapezoids between samples, linear within one): the keyframes' relative yaw,
// so that a turning platform's keyframes start with their own headings (Eq. K11 needs them).
// The gyro bias is unknown here; its drift is what the solve below removes.
std::vector<double> GyroYawAtKeyframes(const sensors::ImuSamples& imu,
                                       const std::vector<Keyframe>& kfs,
                                       const Eigen::Vector3d& up_I) {
  std::vector<double> yaw_rad(kfs.size(), 0.0);
  size_t i = 0;
  double integral_rad = 0.0;  // up to imu[i]
  const auto rate = [&](size_t j) { return imu[j].gyro_rad_s.dot(up_I); };
  const auto at = [&](int64_t t_ns) {
    while (i + 1 < imu.size() && imu[i + 1].t_ns <= t_ns) {
      integral_rad += 0.5 * (rate(i) + rate(i + 1)) * NsToSeconds(imu[i + 1].t_ns - imu[i].t_ns);
      ++i;
    }
    if (i + 1 >= imu.size()) return integral_rad;
    const double dt_s = NsToSeconds(t_ns - imu[i].t_ns);
    const double s = dt_s / NsToSeconds(imu[i + 1].t_ns - imu[i].t_ns);
    return integral_rad + dt_s * (rate(i) + 0.5 * s * (rate(i + 1) - rate(i)));
  };
  const double first_rad = at(kfs.front().t_ns);
  for (size_t k = 0; k < kfs.size(); ++k) yaw_rad[k] = at(kfs[k].t_ns) - first_rad;
  return yaw_rad;
}

}  // namespace

GnssInertialKeyframes KeyframesFromGnssAndImu(std::vector<Keyframe>* keyframes,
                                              const sensors::ImuSamples& imu,
                                              const sensors::WheelSamples& wheel,
                                              const sensors::GnssFixes& fixes,
                                              const sensors::EnuConverter& converter,
                                              const sensors::Calibration& calibration,
                                              const GnssInertialKeyframesOptions& options) {
  std::vector<Keyframe>& kfs = *keyframes;
  if (kfs.size() < 2) throw Error("KeyframesFromGnssAndImu: need at least two keyframes");
  if (imu.empty() || imu.front().t_ns > kfs.front().t_ns || imu.back().t_ns < kfs.back().t_ns) {
    throw Error("KeyframesFromGnssAndImu: the IMU samples do not cover the keyframes");
  }
  // 1. Level keyframes turned by the gyro's yaw (R_W_V = R_z(psi_k)), then placed on the
  //    track (Eq. K7) ...
  const Eigen::Quaterniond q_V_I = calibration.q_I_V.conjugate();
  const std::vector<double> gyro_yaw_rad =
      GyroYawAtKeyframes(imu, kfs, calibration.q_I_V * Eigen::Vector3d::UnitZ());
  for (size_t k = 0; k < kfs.size(); ++k) {
    kfs[k].q_W_I =
        (Eigen::Quaterniond(Eigen::AngleAxisd(gyro_yaw_rad[k], Eigen::Vector3d::UnitZ())) * q_V_I)
            .normalized();
    kfs[k].b_g.setZero();
    kfs[k].b_a.setZero();
  }
  GnssInertialKeyframes result;
  result.placement = PlaceKeyframesOnGnss(keyframes, fixes, converter, calibration.p_I_A,
                                          calibration.q_I_V, options.placement);
  // ... each turned to its own heading where that is trusted (Eq. K9, K10): R_W_I =
  // R_z(psi) R_V_I with psi the heading of the antenna velocity; the antenna stays where the
  // track put it.
  for (size_t k = 0; k < kfs.size(); ++k) {
    if (!result.placement.heading[k]) continue;
    Keyframe& kf = kfs[k];
    const Eigen::Vector3d p_W_A = kf.p_W_I + kf.q_W_I * calibration.p_I_A;
    const double psi = std::atan2(kf.v_W_I.y(), kf.v_W_I.x());
    kf.q_W_I =
        (Eigen::Quaterniond(Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ())) * q_V_I).normalized();
    kf.p_W_I = p_W_A - kf.q_W_I * calibration.p_I_A;
  }

  // 2. The GNSS-inertial problem.
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  geometry::RightQuaternionManifold quaternion_manifold;
  for (Keyframe& kf : kfs)
    problem.AddParameterBlock(kf.q_W_I.coeffs().data(), 4, &quaternion_manifold);
  KeyframeImuOptions imu_options;
  imu_options.noise = options.imu_noise;
  imu_options.gravity_m_s2 = options.gravity_m_s2;
  imu_options.num_threads = options.num_threads;
  AddImuFactors(&problem, imu, keyframes, imu_options);
  sensors::Calibration held = calibration;
  KeyframeGnssOptions gnss = options.gnss;
  gnss.estimate_lever_arm = false;
  result.gnss_factors = AddGnssFactors(&problem, fixes, converter, keyframes, &held, gnss);
  if (!wheel.empty()) {
    problem.AddParameterBlock(held.q_I_V.coeffs().data(), 4, &quaternion_manifold);
    KeyframeWheelOptions wheel_options = options.wheel;
    // q_I_V is estimated about its given value: held there, its error (degrees for a nominal
    // value) would tilt every keyframe through the non-holonomic rows (measured 3 deg of roll
    // and pitch for the simulator's nominal one, absorbed by a 0.7 m/s^2 accelerometer bias).
    wheel_options.estimate_vehicle_rotation = true;
    problem.AddResidualBlock(
        new factors::QuaternionPriorFactor(
            held.q_I_V, Eigen::Matrix3d::Identity() /
                            (options.vehicle_rotation_prior_sigma_deg * M_PI / 180.0)),
        nullptr, held.q_I_V.coeffs().data());
    wheel_options.estimate_vehicle_translation = false;
    wheel_options.estimate_radii = true;
    wheel_options.estimate_track_width = false;
    result.wheel_factors = AddWheelFactors(&problem, imu, wheel, keyframes, &held, wheel_options);
  }
  AddBiasPriors(&problem, &kfs.front(), options.gyro_bias_prior_sigma_rad_s,
                options.accel_bias_prior_sigma_m_s2);

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.num_threads = options.num_threads;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
  if (!summary.IsSolutionUsable()) {
    throw Error("KeyframesFromGnssAndImu: the GNSS-inertial solve failed: " + summary.message);
  }
  for (Keyframe& kf : kfs) kf.q_W_I.normalize();
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.termination = summary.message;
  return result;
}

}  // namespace estimation
}  // namespace autocal
