#include "autocal/estimation/gnss_inertial_keyframes.h"

#include <ceres/ceres.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/calibration_observability.h"
#include "autocal/estimation/keyframe_solver_options.h"
#include "autocal/factors/prior_factors.h"
#include "autocal/geometry/manifolds.h"
#include "estimation/keyframe_interpolation.h"

namespace autocal {
namespace estimation {

namespace {

using internal::ForwardHeading;
using internal::NearestFlagged;
using internal::WrapAngle;

// The marginal covariance of kf's five state blocks in their tangent spaces, or empty when the
// problem leaves one of their directions undetermined (a rank-deficient Jacobian). From the
// sparse LDL^T of J^T J with the blocks in problem order (ComputeBlockCovariance): the
// ceres::Covariance this replaced ordered them by address, so the window's start, and with it
// a whole stream, moved at the rounding level with the heap's layout.
std::optional<Eigen::Matrix<double, 15, 15>> FirstKeyframeCovariance(ceres::Problem* problem,
                                                                     Keyframe* kf,
                                                                     int num_threads) {
  std::vector<EstimatedBlock> blocks(5);
  blocks[0].data = kf->q_W_I.coeffs().data();
  blocks[0].manifold = sensors::BlockManifold::kRightQuaternion;
  const std::vector<double*> vectors = {kf->p_W_I.data(), kf->v_W_I.data(), kf->b_g.data(),
                                        kf->b_a.data()};
  for (size_t i = 0; i < vectors.size(); ++i) blocks[i + 1].data = vectors[i];
  for (EstimatedBlock& block : blocks) block.size = 3;
  const BlockCovariance covariance = ComputeBlockCovariance(blocks, problem, num_threads);
  if (!covariance.ok) return std::nullopt;
  return Eigen::Matrix<double, 15, 15>(covariance.matrix);
}

// The GNSS-inertial problem over the placed keyframes (step 2 of KeyframesFromGnssAndImu), solved
// in place, with the fixes' std scaled by gnss.noise_scale.
struct StatesSolve {
  ceres::Solver::Summary summary;
  int gnss_factors = 0;
  int wheel_factors = 0;
  std::optional<Eigen::Matrix<double, 15, 15>> first_covariance;
};
StatesSolve SolveStates(const sensors::ImuSamples& imu, const WheelData& wheel,
                        const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
                        const sensors::Calibration& calibration,
                        const GnssInertialKeyframesOptions& options,
                        const KeyframeGnssOptions& gnss, std::vector<Keyframe>* keyframes) {
  std::vector<Keyframe>& kfs = *keyframes;
  StatesSolve out;
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
  out.gnss_factors = AddGnssFactors(&problem, imu, fixes, converter, keyframes, &held, gnss);
  if (!wheel.empty()) {
    problem.AddParameterBlock(held.q_I_V.coeffs().data(), 4, &quaternion_manifold);
    KeyframeWheelOptions wheel_options = options.wheel;
    wheel_options.gravity_m_s2 = options.gravity_m_s2;
    // q_I_V is estimated about its given value: held there, its error (degrees for a nominal
    // value) would tilt every keyframe through the non-holonomic rows (measured 3 deg of roll
    // and pitch for the simulator's nominal one, absorbed by a 0.7 m/s^2 accelerometer bias).
    wheel_options.estimate_vehicle_rotation = true;
    problem.AddResidualBlock(
        new factors::QuaternionPriorFactor(
            held.q_I_V,
            Eigen::Matrix3d::Identity() / (options.vehicle_rotation_prior_sigma_deg * kDegToRad)),
        nullptr, held.q_I_V.coeffs().data());
    wheel_options.estimate_vehicle_translation = false;
    wheel_options.estimate_radii = true;
    // An odometry twist's effective track: a skid steer's slip puts it far from any nominal.
    wheel_options.estimate_track_width = wheel.form == sensors::WheelForm::kSpeedYawRate;
    out.wheel_factors = AddWheelFactors(&problem, imu, wheel, keyframes, &held, wheel_options);
  }
  AddBiasPriors(&problem, &kfs.front(), options.gyro_bias_prior_sigma_rad_s,
                options.accel_bias_prior_sigma_m_s2);

  const ceres::Solver::Options solver_options =
      KeyframeSolverOptions(options.max_iterations, options.num_threads);
  ceres::Solve(solver_options, &problem, &out.summary);
  if (!out.summary.IsSolutionUsable()) {
    throw Error("KeyframesFromGnssAndImu: the GNSS-inertial solve failed: " + out.summary.message);
  }
  if (options.first_keyframe_covariance) {
    out.first_covariance = FirstKeyframeCovariance(&problem, &kfs.front(), options.num_threads);
  }
  return out;
}

// Eq. K9b's anchor on one side of a stretch of keyframes without a heading: the circular mean of
// the corrections the headings within window_ns of the stretch's edge keyframe ask (towards
// `step`, +1 or -1), each weighted by its inverse variance (speed / sigma_v)^2, and their
// weighted mean time (s after the first keyframe): a constant gyro bias turns the correction
// linearly in time.
struct Anchor {
  double t_s = 0.0;
  double correction_rad = 0.0;
};
Anchor AnchorAt(const std::vector<Keyframe>& kfs, const GnssPlacement& placement,
                const std::vector<double>& correction_rad, size_t edge, int step,
                int64_t window_ns) {
  double s = 0.0, c = 0.0, weight_sum = 0.0, t_sum = 0.0;
  for (ptrdiff_t j = static_cast<ptrdiff_t>(edge);
       j >= 0 && j < static_cast<ptrdiff_t>(kfs.size()) &&
       std::abs(kfs[static_cast<size_t>(j)].t_ns - kfs[edge].t_ns) <= window_ns;
       j += step) {
    const size_t i = static_cast<size_t>(j);
    if (!placement.heading[i]) continue;
    const double w = kfs[i].v_W_I.head<2>().squaredNorm() /
                     (placement.velocity_sigma_m_s[i] * placement.velocity_sigma_m_s[i]);
    s += w * std::sin(correction_rad[i]);
    c += w * std::cos(correction_rad[i]);
    t_sum += w * NsToSeconds(kfs[i].t_ns - kfs.front().t_ns);
    weight_sum += w;
  }
  return {t_sum / weight_sum, std::atan2(s, c)};
}

// Eqs. K9, K9b: the yaw correction about z_W of every keyframe. One with a trusted heading gets
// its vehicle x axis along it; one without (standing, slow, in an outage, reversing) keeps its
// gyro yaw relative to the keyframes with a heading around it: the corrections of the anchors on
// either side, interpolated in time (one side at the log's ends). The gyro's drift is then that
// over the stretch, not over the log. Empty when no keyframe has a heading.
std::vector<double> HeadingCorrections(const std::vector<Keyframe>& kfs,
                                       const GnssPlacement& placement,
                                       const Eigen::Quaterniond& q_I_V, int64_t window_ns) {
  if (placement.num_headings == 0) return {};
  std::vector<double> correction_rad(kfs.size(), 0.0);
  for (size_t k = 0; k < kfs.size(); ++k) {
    if (!placement.heading[k]) continue;
    const Eigen::Vector3d& v = kfs[k].v_W_I;
    correction_rad[k] = WrapAngle(std::atan2(v.y(), v.x()) - ForwardHeading(kfs[k], q_I_V));
  }
  const std::vector<std::optional<size_t>> before = NearestFlagged(placement.heading, +1);
  const std::vector<std::optional<size_t>> after = NearestFlagged(placement.heading, -1);
  std::vector<double> out = correction_rad;
  std::optional<Anchor> b, a;  // of the stretch k lies in
  for (size_t k = 0; k < kfs.size(); ++k) {
    if (placement.heading[k]) continue;
    if (k == 0 || placement.heading[k - 1]) {  // a stretch begins
      b.reset();
      a.reset();
      if (before[k]) b = AnchorAt(kfs, placement, correction_rad, *before[k], -1, window_ns);
      if (after[k]) a = AnchorAt(kfs, placement, correction_rad, *after[k], +1, window_ns);
    }
    if (!a || !b) {
      out[k] = (a ? a : b)->correction_rad;
      continue;
    }
    const double t_s = NsToSeconds(kfs[k].t_ns - kfs.front().t_ns);
    out[k] = b->correction_rad +
             WrapAngle(a->correction_rad - b->correction_rad) * (t_s - b->t_s) / (a->t_s - b->t_s);
  }
  return out;
}

}  // namespace

GnssInertialKeyframes KeyframesFromGnssAndImu(
    std::vector<Keyframe>* keyframes, const sensors::ImuSamples& imu, const WheelData& wheel,
    const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
    const sensors::Calibration& calibration, const GnssInertialKeyframesOptions& options) {
  std::vector<Keyframe>& kfs = *keyframes;
  if (kfs.size() < 2) throw Error("KeyframesFromGnssAndImu: need at least two keyframes");
  if (imu.empty() || imu.front().t_ns > kfs.front().t_ns || imu.back().t_ns < kfs.back().t_ns) {
    throw Error("KeyframesFromGnssAndImu: the IMU samples do not cover the keyframes");
  }
  // 1. Level keyframes turned by the gyro's yaw (R_W_V = R_z(psi_k)), then placed on the
  //    track (Eq. K7) ...
  const Eigen::Quaterniond q_V_I = calibration.q_I_V.conjugate();
  const std::vector<double> gyro_yaw_rad =
      internal::GyroYawAtKeyframes(imu, kfs, calibration.q_I_V * Eigen::Vector3d::UnitZ());
  for (size_t k = 0; k < kfs.size(); ++k) {
    kfs[k].q_W_I =
        (Eigen::Quaterniond(Eigen::AngleAxisd(gyro_yaw_rad[k], Eigen::Vector3d::UnitZ())) * q_V_I)
            .normalized();
    kfs[k].b_g.setZero();
    kfs[k].b_a.setZero();
  }
  GnssInertialKeyframes result;
  result.placement =
      PlaceKeyframesOnGnss(keyframes, FixesOnImuClock(fixes, calibration.time_offset_gnss_imu_s),
                           converter, calibration.p_I_A, calibration.q_I_V, options.placement);
  // ... each turned to its own heading where that is trusted (Eq. K9, K10): R_W_I =
  // R_z(psi) R_V_I with psi the heading of the antenna velocity; the others by the correction
  // of the headings around them (Eq. K9b). The antenna stays where the track put it.
  const std::vector<double> correction_rad = HeadingCorrections(
      kfs, result.placement, calibration.q_I_V, SecondsToNs(options.placement.heading_window_s));
  for (size_t k = 0; k < correction_rad.size(); ++k) {
    Keyframe& kf = kfs[k];
    const Eigen::Vector3d p_W_A = kf.p_W_I + kf.q_W_I * calibration.p_I_A;
    const double psi = result.placement.heading[k]
                           ? std::atan2(kf.v_W_I.y(), kf.v_W_I.x())
                           : ForwardHeading(kf, calibration.q_I_V) + correction_rad[k];
    kf.q_W_I =
        (Eigen::Quaterniond(Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ())) * q_V_I).normalized();
    kf.p_W_I = p_W_A - kf.q_W_I * calibration.p_I_A;
  }

  // 2. The GNSS-inertial problem, solved again with the fixes' std scaled where they scatter
  //    beyond it (Eq. N2).
  KeyframeGnssOptions gnss = options.gnss;
  gnss.gravity_m_s2 = options.gravity_m_s2;
  gnss.estimate_lever_arm = false;
  StatesSolve solve =
      SolveStates(imu, wheel, fixes, converter, calibration, options, gnss, keyframes);
  if (options.gnss_noise_from_residuals) {
    sensors::Calibration held = calibration;
    result.gnss_noise = MeasureGnssNoise(imu, fixes, converter, keyframes, &held, gnss);
    const GnssStdScale measured = result.gnss_noise->Scale();
    if (!measured.IsOne() && !(measured == gnss.noise_scale)) {
      gnss.noise_scale = measured;
      solve = SolveStates(imu, wheel, fixes, converter, calibration, options, gnss, keyframes);
    }
  }
  result.gnss_std_scale = gnss.noise_scale;
  result.gnss_factors = solve.gnss_factors;
  result.wheel_factors = solve.wheel_factors;
  result.first_covariance = solve.first_covariance;
  for (Keyframe& kf : kfs) kf.q_W_I.normalize();
  result.initial_cost = solve.summary.initial_cost;
  result.final_cost = solve.summary.final_cost;
  result.termination = solve.summary.message;
  return result;
}

}  // namespace estimation
}  // namespace autocal
