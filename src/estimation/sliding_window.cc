#include "autocal/estimation/sliding_window.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/factors/prior_factors.h"
#include "estimation/point_selection.h"
#include "estimation/sliding_window_internal.h"
#include "estimation/window_solver.h"

namespace autocal {
namespace estimation {

using internal::AttachedFactor;
using internal::StateBlocks;

namespace {

constexpr int64_t kNoStamp = std::numeric_limits<int64_t>::min();

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void CheckPositive(double value, const char* name) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw Error(std::string("SlidingWindowOptions: ") + name + " must be positive and finite");
  }
}

void CheckNonNegative(double value, const char* name) {
  if (!(value >= 0.0) || !std::isfinite(value)) {
    throw Error(std::string("SlidingWindowOptions: ") + name + " must be non-negative and finite");
  }
}

void CheckOptions(const SlidingWindowOptions& o) {
  if (o.window_size < 2) throw Error("SlidingWindowOptions: window_size must be at least 2");
  if (o.point_linearizations_per_update < 0) {
    throw Error("SlidingWindowOptions: point_linearizations_per_update must be >= 0");
  }
  if (o.solver_iterations < 1) {
    throw Error("SlidingWindowOptions: solver_iterations must be at least 1");
  }
  if (o.max_wheel_samples_per_interval < 0 || o.max_residuals_per_sweep < 0) {
    throw Error("SlidingWindowOptions: sample limits must not be negative");
  }
  if (o.max_plane_misses < 0 || o.max_plane_misses > 255) {
    throw Error("SlidingWindowOptions: max_plane_misses must be in [0, 255], got " +
                std::to_string(o.max_plane_misses));
  }
  CheckPositive(o.residual_voxel_m, "residual_voxel_m");
  CheckNonNegative(o.residual_max_range_m, "residual_max_range_m");
  CheckPositive(o.map_voxel_m, "map_voxel_m");
  CheckPositive(o.point_sigma_m, "point_sigma_m");
  CheckPositive(o.solver_function_tolerance, "solver_function_tolerance");
  CheckPositive(o.max_point_to_plane_m, "max_point_to_plane_m");
  CheckNonNegative(o.gate_extrinsic_factor, "gate_extrinsic_factor");
  CheckNonNegative(o.gate_extrinsic_free_deg, "gate_extrinsic_free_deg");
  CheckNonNegative(o.settled_extrinsic_deg, "settled_extrinsic_deg");
  for (double tolerance : {o.reassociation_tolerance_m, o.map_rebuild_tolerance_m,
                           o.relinearization_tolerance_m}) {
    if (!(tolerance >= 0.0) || !std::isfinite(tolerance)) {
      throw Error("SlidingWindowOptions: reassociation_tolerance_m, map_rebuild_tolerance_m and "
                  "relinearization_tolerance_m must be finite and >= 0");
    }
  }
  if (o.partner_keyframe_offsets.empty() ||
      std::count(o.partner_keyframe_offsets.begin(), o.partner_keyframe_offsets.end(), 0) > 0) {
    throw Error("SlidingWindowOptions: partner_keyframe_offsets must be non-empty and non-zero");
  }
  std::vector<int> offsets = o.partner_keyframe_offsets;
  std::sort(offsets.begin(), offsets.end());
  if (std::adjacent_find(offsets.begin(), offsets.end()) != offsets.end()) {
    throw Error("SlidingWindowOptions: partner_keyframe_offsets must not repeat an offset");
  }
  if (o.settled_partner_count < 1) {
    throw Error("SlidingWindowOptions: settled_partner_count must be >= 1");
  }
  CheckPositive(o.wheel_non_holonomic_sigma_m_s, "wheel_non_holonomic_sigma_m_s");
  if (!(o.wheel_non_holonomic_correlation_s >= 0.0) ||
      !std::isfinite(o.wheel_non_holonomic_correlation_s)) {
    throw Error("SlidingWindowOptions: wheel_non_holonomic_correlation_s must be finite and >= 0");
  }
  CheckPositive(o.wheel.noise_rad_s, "wheel.noise_rad_s");
  CheckPositive(o.imu.gravity_m_s2, "imu.gravity_m_s2");
  if (!(o.wheel_gyro_mean_span_s >= 0.0) || !std::isfinite(o.wheel_gyro_mean_span_s)) {
    throw Error("SlidingWindowOptions: wheel_gyro_mean_span_s must be finite and >= 0");
  }
  if (o.keyframe_lead_s < 0.0 || o.imu_coverage_margin_s < 0.0 ||
      o.min_keyframe_interval_s < 0.0) {
    throw Error("SlidingWindowOptions: keyframe_lead_s, imu_coverage_margin_s and "
                "min_keyframe_interval_s must be >= 0");
  }
  const SlidingWindowCalibrationPrior& c = o.calibration_prior;
  for (double s : {c.extrinsic_rotation_deg, c.extrinsic_translation_m, c.time_offset_s,
                   c.wheel_radius_m, c.track_width_m, c.vehicle_rotation_deg,
                   c.vehicle_translation_m, c.gnss_lever_arm_m}) {
    CheckPositive(s, "calibration_prior sigmas");
  }
  if (c.mean) {
    const sensors::Calibration& m = *c.mean;
    const bool finite = m.q_I_L.coeffs().allFinite() && m.p_I_L.allFinite() &&
                        m.q_I_V.coeffs().allFinite() && m.p_I_V.allFinite() &&
                        m.p_I_A.allFinite() && std::isfinite(m.time_offset_lidar_imu_s) &&
                        std::isfinite(m.wheel_radius_left_m) &&
                        std::isfinite(m.wheel_radius_right_m) && std::isfinite(m.track_width_m);
    if (!finite || m.q_I_L.norm() < 0.5 || m.q_I_V.norm() < 0.5) {
      throw Error(
          "SlidingWindowOptions: calibration_prior.mean must be finite with unit "
          "quaternions");
    }
  }
  const SlidingWindowInitialStateSigmas& x = o.initial_state_sigmas;
  for (double s : {x.rotation_deg, x.position_m, x.velocity_m_s, x.gyro_bias_rad_s,
                   x.accel_bias_m_s2}) {
    CheckPositive(s, "initial_state_sigmas");
  }
}

AttachedFactor QuaternionPrior(Eigen::Quaterniond* q, const Eigen::Quaterniond& mean,
                               double sigma_rad, ceres::LossFunction* loss) {
  AttachedFactor f;
  f.cost = std::make_unique<factors::QuaternionPriorFactor>(
      mean.normalized(), Eigen::Matrix3d::Identity() / sigma_rad);
  f.loss = loss;
  f.blocks = {q->coeffs().data()};
  return f;
}

AttachedFactor VectorPrior(double* x, const double* mean, int size, double sigma,
                           ceres::LossFunction* loss) {
  AttachedFactor f;
  f.cost = std::make_unique<factors::VectorPriorFactor>(
      Eigen::Map<const Eigen::VectorXd>(mean, size), Eigen::MatrixXd::Identity(size, size) / sigma);
  f.loss = loss;
  f.blocks = {x};
  return f;
}

bool AllFinite(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return a.allFinite() && b.allFinite();
}

}  // namespace

SlidingWindowEstimator::SlidingWindowEstimator(const SlidingWindowOptions& options,
                                               const sensors::Calibration& initial_calibration,
                                               const SlidingWindowState& initial_state)
    : options_(options),
      g_W_(0.0, 0.0, -options.imu.gravity_m_s2),
      calibration_(initial_calibration),
      newest_wheel_ns_(kNoStamp),
      newest_gnss_ns_(kNoStamp),
      newest_sweep_ns_(kNoStamp),
      terms_pool_(std::make_unique<TermsPool>()) {
  CheckOptions(options_);
  if (options_.enu_origin_lla) {
    const Eigen::Vector3d& o = *options_.enu_origin_lla;
    enu_.emplace(o.x(), o.y(), o.z());
  }
  imu_loss_.reset(factors::MakeLossFunction(options_.loss.imu));
  wheel_loss_.reset(factors::MakeLossFunction(options_.loss.wheel));
  gnss_loss_.reset(factors::MakeLossFunction(options_.loss.gnss));
  // The point groups apply the LiDAR loss themselves (Eq. P9); its options are checked here.
  const std::unique_ptr<ceres::LossFunction> lidar_loss(
      factors::MakeLossFunction(options_.loss.lidar));
  prior_loss_.reset(factors::MakeLossFunction(options_.loss.prior));

  // Keyframe 0 is the initial state, tied to it by a state prior (Eq. F42) that fixes the
  // gauge; it is marginalized into the window prior with the keyframe.
  auto kf = std::make_unique<WindowKeyframe>();
  kf->id = next_keyframe_id_++;
  kf->state = initial_state;
  kf->state.q_W_I.normalize();
  const SlidingWindowInitialStateSigmas& s = options_.initial_state_sigmas;
  factors::StatePrior prior;
  prior.state.q_W_I = kf->state.q_W_I;
  prior.state.p_W_I = kf->state.p_W_I;
  prior.state.v_W_I = kf->state.v_W_I;
  prior.b_g = kf->state.b_g;
  prior.b_a = kf->state.b_a;
  Eigen::Matrix<double, 15, 1> sigmas;
  sigmas << Eigen::Vector3d::Constant(s.rotation_deg * kDegToRad),
      Eigen::Vector3d::Constant(s.position_m), Eigen::Vector3d::Constant(s.velocity_m_s),
      Eigen::Vector3d::Constant(s.gyro_bias_rad_s), Eigen::Vector3d::Constant(s.accel_bias_m_s2);
  prior.sqrt_information = sigmas.cwiseInverse().asDiagonal();
  AttachedFactor state_prior;
  state_prior.cost = std::make_unique<factors::StatePriorFactor>(prior);
  state_prior.loss = prior_loss_.get();
  state_prior.blocks = StateBlocks(&kf->state);
  kf->factors.push_back(std::move(state_prior));
  window_.push_back(std::move(kf));

  // Calibration priors (never marginalized: they touch no keyframe).
  const SlidingWindowCalibrationPrior& c = options_.calibration_prior;
  const SlidingWindowEstimatedBlocks& e = options_.estimate;
  ceres::LossFunction* loss = prior_loss_.get();
  sensors::Calibration& x = calibration_;
  const sensors::Calibration& m = c.mean ? *c.mean : initial_calibration;
  if (e.extrinsic_rotation) {
    calibration_priors_.push_back(
        QuaternionPrior(&x.q_I_L, m.q_I_L, c.extrinsic_rotation_deg * kDegToRad, loss));
  }
  if (e.extrinsic_translation) {
    calibration_priors_.push_back(
        VectorPrior(x.p_I_L.data(), m.p_I_L.data(), 3, c.extrinsic_translation_m, loss));
  }
  if (e.time_offset) {
    calibration_priors_.push_back(VectorPrior(
        &x.time_offset_lidar_imu_s, &m.time_offset_lidar_imu_s, 1, c.time_offset_s, loss));
  }
  if (e.wheel_radii) {
    calibration_priors_.push_back(
        VectorPrior(&x.wheel_radius_left_m, &m.wheel_radius_left_m, 1, c.wheel_radius_m, loss));
    calibration_priors_.push_back(
        VectorPrior(&x.wheel_radius_right_m, &m.wheel_radius_right_m, 1, c.wheel_radius_m, loss));
  }
  if (e.track_width) {
    calibration_priors_.push_back(
        VectorPrior(&x.track_width_m, &m.track_width_m, 1, c.track_width_m, loss));
  }
  if (e.vehicle_frame) {
    calibration_priors_.push_back(
        QuaternionPrior(&x.q_I_V, m.q_I_V, c.vehicle_rotation_deg * kDegToRad, loss));
    calibration_priors_.push_back(
        VectorPrior(x.p_I_V.data(), m.p_I_V.data(), 3, c.vehicle_translation_m, loss));
  }
  if (e.gnss_lever_arm) {
    calibration_priors_.push_back(
        VectorPrior(x.p_I_A.data(), m.p_I_A.data(), 3, c.gnss_lever_arm_m, loss));
  }
}

SlidingWindowEstimator::~SlidingWindowEstimator() = default;

// ---------------------------------------------------------------------------------------------
// Streaming input.

bool SlidingWindowEstimator::AddImu(const sensors::ImuSample& sample) {
  if (!AllFinite(sample.gyro_rad_s, sample.accel_m_s2)) {
    throw Error("SlidingWindowEstimator::AddImu: non-finite sample at t_ns " +
                std::to_string(sample.t_ns));
  }
  if (!imu_.empty() && sample.t_ns <= imu_.back().t_ns) {
    ++counters_.out_of_order;
    return false;
  }
  if (imu_.empty() && sample.t_ns > window_.front()->state.t_ns) {
    throw Error("SlidingWindowEstimator::AddImu: the IMU stream must start at or before the "
                "initial state's time (first sample at t_ns " + std::to_string(sample.t_ns) +
                ", initial state at " + std::to_string(window_.front()->state.t_ns) + ")");
  }
  imu_.push_back(sample);
  ++counters_.imu_accepted;
  ProcessCoveredSweeps();
  return true;
}

bool SlidingWindowEstimator::AddWheel(const sensors::WheelSample& sample) {
  if (!std::isfinite(sample.left_rad_s) || !std::isfinite(sample.right_rad_s)) {
    throw Error("SlidingWindowEstimator::AddWheel: non-finite rates at t_ns " +
                std::to_string(sample.t_ns));
  }
  if (sample.t_ns <= newest_wheel_ns_) {
    ++counters_.out_of_order;
    return false;
  }
  newest_wheel_ns_ = sample.t_ns;
  if (sample.t_ns <= latest_state().t_ns) {
    ++counters_.late;
    return false;
  }
  wheel_.push_back(sample);
  ++counters_.wheel_accepted;
  return true;
}

bool SlidingWindowEstimator::AddGnss(const sensors::GnssFix& fix) {
  if (!enu_) enu_.emplace(fix.lat_deg, fix.lon_deg, fix.alt_m);  // W at the first fix
  GnssPosition position;
  position.t_ns = fix.t_ns;
  position.p_W_A = enu_->ToEnu(fix);
  position.sigma_enu_m = fix.std_enu_m;
  return AddGnss(position);
}

bool SlidingWindowEstimator::AddGnss(const GnssPosition& position) {
  if (!position.p_W_A.allFinite() || !position.sigma_enu_m.allFinite() ||
      !(position.sigma_enu_m.minCoeff() > 0.0)) {
    throw Error("SlidingWindowEstimator::AddGnss: non-finite position or non-positive sigma at "
                "t_ns " + std::to_string(position.t_ns));
  }
  if (position.t_ns <= newest_gnss_ns_) {
    ++counters_.out_of_order;
    return false;
  }
  newest_gnss_ns_ = position.t_ns;
  if (position.t_ns <= latest_state().t_ns) {
    ++counters_.late;
    return false;
  }
  gnss_.push_back(position);
  ++counters_.gnss_accepted;
  return true;
}

bool SlidingWindowEstimator::AddSweep(lidar::LidarSweep sweep) {
  lidar::CheckPointCloud(sweep.cloud, "SlidingWindowEstimator::AddSweep: sweep");
  if (!sweep.cloud.empty() && !sweep.cloud.has_time()) {
    throw Error("SlidingWindowEstimator::AddSweep: the sweep at t_ns " +
                std::to_string(sweep.t_ns) + " has no per-point time");
  }
  if (sweep.t_ns <= newest_sweep_ns_) {
    ++counters_.out_of_order;
    return false;
  }
  newest_sweep_ns_ = sweep.t_ns;
  if (TooCloseToNewestKeyframe(sweep)) {
    ++counters_.late;
    return false;
  }
  pending_sweeps_.push_back(std::move(sweep));
  ++counters_.sweeps_accepted;
  ProcessCoveredSweeps();
  return true;
}

int64_t SlidingWindowEstimator::KeyframeTimeOf(const lidar::LidarSweep& sweep) const {
  return sweep.t_ns + SecondsToNs(calibration_.time_offset_lidar_imu_s - options_.keyframe_lead_s);
}

bool SlidingWindowEstimator::TooCloseToNewestKeyframe(const lidar::LidarSweep& sweep) const {
  return KeyframeTimeOf(sweep) - latest_state().t_ns <
         std::max<int64_t>(1, SecondsToNs(options_.min_keyframe_interval_s));
}

void SlidingWindowEstimator::ProcessCoveredSweeps() {
  while (!pending_sweeps_.empty() && !imu_.empty()) {
    const lidar::LidarSweep& sweep = pending_sweeps_.front();
    const double duration_s = sweep.cloud.has_time() ? sweep.cloud.time_s.maxCoeff() : 0.0;
    const int64_t needed_ns =
        sweep.t_ns + SecondsToNs(duration_s + calibration_.time_offset_lidar_imu_s +
                                 options_.imu_coverage_margin_s);
    if (imu_.back().t_ns < needed_ns) return;
    lidar::LidarSweep covered = std::move(pending_sweeps_.front());
    pending_sweeps_.pop_front();
    // The offset estimate may have moved since the sweep arrived.
    if (TooCloseToNewestKeyframe(covered)) {
      ++counters_.late;
    } else {
      Update(std::move(covered));
    }
  }
}

// ---------------------------------------------------------------------------------------------
// One window update.

void SlidingWindowEstimator::Update(lidar::LidarSweep sweep) {
  const auto start = std::chrono::steady_clock::now();
  timing_ = SlidingWindowUpdateTiming();
  AddKeyframe(std::move(sweep));
  RelinearizeImuFactors();

  const auto association_start = std::chrono::steady_clock::now();
  AssociatePoints();
  timing_.association_s = SecondsSince(association_start);

  const auto build_start = std::chrono::steady_clock::now();
  std::unique_ptr<ProblemBuild> build = BuildProblem();
  timing_.build_s = SecondsSince(build_start);

  const auto solve_start = std::chrono::steady_clock::now();
  Solve(&build);
  timing_.solve_s = SecondsSince(solve_start);

  if (static_cast<int>(window_.size()) > options_.window_size) {
    // The point groups the marginalization drops still count in this update's point RMS.
    dropped_point_squared_m2_ = SquaredPointDistances(true);
    const auto marginalization_start = std::chrono::steady_clock::now();
    std::unique_ptr<MarginalizationPrior> prior = MarginalizeOldest(build.get());
    build.reset();  // the problem refers to the factors about to be dropped
    DropOldest(std::move(prior));
    timing_.marginalization_s = SecondsSince(marginalization_start);
  }
  TrimImuBuffer();
  recent_q_I_L_.push_back(calibration_.q_I_L);
  while (static_cast<int>(recent_q_I_L_.size()) > options_.window_size) recent_q_I_L_.pop_front();
  ++counters_.updates;
  timing_.total_s = SecondsSince(start);
}

void SlidingWindowEstimator::AddKeyframe(lidar::LidarSweep sweep) {
  WindowKeyframe& previous = *window_.back();
  auto kf = std::make_unique<WindowKeyframe>();
  kf->tried_at = std::move(spare_tried_at_);  // overwritten before use
  kf->id = next_keyframe_id_++;
  kf->state.t_ns = KeyframeTimeOf(sweep);

  // Prediction with the IMU from the previous keyframe (Eq. F8); biases carried over.
  sensors::PreintegrationOptions preintegration;
  preintegration.gravity_m_s2 = options_.imu.gravity_m_s2;
  kf->imu_from_previous = std::make_unique<sensors::ImuPreintegration>(
      options_.imu.noise, preintegration, previous.state.b_g, previous.state.b_a);
  kf->imu_from_previous->Integrate(imu_, previous.state.t_ns, kf->state.t_ns);
  sensors::NavStated x;
  x.q_W_I = previous.state.q_W_I;
  x.p_W_I = previous.state.p_W_I;
  x.v_W_I = previous.state.v_W_I;
  x = kf->imu_from_previous->Predict(x, previous.state.b_g, previous.state.b_a);
  kf->state.q_W_I = x.q_W_I.normalized();
  kf->state.p_W_I = x.p_W_I;
  kf->state.v_W_I = x.v_W_I;
  kf->state.b_g = previous.state.b_g;
  kf->state.b_a = previous.state.b_a;

  kf->residual_points =
      internal::Thin(internal::OnePointPerVoxel(sweep.cloud, options_.residual_voxel_m,
                                                options_.min_range_m, options_.residual_max_range_m),
                     options_.max_residuals_per_sweep);
  kf->map_points =
      internal::OnePointPerVoxel(sweep.cloud, options_.map_voxel_m, options_.min_range_m);
  const size_t num_residuals = kf->residual_points.size();
  kf->residual_p_L.resize(3, static_cast<Eigen::Index>(num_residuals));
  kf->residual_time_s.resize(num_residuals);
  kf->residual_ranges_m.resize(num_residuals);
  for (size_t r = 0; r < num_residuals; ++r) {
    const int i = kf->residual_points[r];
    kf->residual_p_L.col(static_cast<Eigen::Index>(r)) = sweep.cloud.points.col(i);
    kf->residual_time_s[r] = sweep.cloud.time_s(i);
    kf->residual_ranges_m[r] = sweep.cloud.points.col(i).norm();
    kf->residual_max_range_m = std::max(kf->residual_max_range_m, kf->residual_ranges_m[r]);
  }
  kf->sweep_duration_s = sweep.cloud.has_time() ? sweep.cloud.time_s.maxCoeff() : 0.0;
  kf->sweep = std::move(sweep);

  AttachIntervalMeasurements(&previous, kf->state.t_ns);
  window_.push_back(std::move(kf));
}

void SlidingWindowEstimator::AttachIntervalMeasurements(WindowKeyframe* from, int64_t t_end_ns) {
  sensors::PreintegrationOptions preintegration;
  preintegration.gravity_m_s2 = options_.imu.gravity_m_s2;
  SlidingWindowState& s = from->state;
  sensors::Calibration& c = calibration_;

  // Wheel samples of (t_from, t_end], evenly thinned.
  std::vector<sensors::WheelSample> wheel;
  while (!wheel_.empty() && wheel_.front().t_ns <= t_end_ns) {
    wheel.push_back(wheel_.front());
    wheel_.pop_front();
  }
  std::vector<int> all(wheel.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  factors::WheelFactorOptions wheel_options = factors::WheelFactorOptions::FromEncoderNoise(
      options_.wheel, 0.5 * (c.wheel_radius_left_m + c.wheel_radius_right_m), c.track_width_m);
  const double gyro_sample_sigma_rad_s =
      options_.imu.noise.gyroscope_noise_density * std::sqrt(options_.imu.noise.update_rate_hz);
  const std::vector<int> used = internal::Thin(all, options_.max_wheel_samples_per_interval);
  // Eq. K6 at the spacing of the samples used.
  const double non_holonomic_sigma_m_s =
      options_.wheel_non_holonomic_sigma_m_s *
      NonHolonomicSigmaScale(options_.wheel_non_holonomic_correlation_s,
                             used.empty() ? 0.0
                                          : NsToSeconds(t_end_ns - s.t_ns) /
                                                static_cast<double>(used.size()));
  wheel_options.non_holonomic = options_.wheel_non_holonomic;
  wheel_options.lateral_sigma_m_s = non_holonomic_sigma_m_s;
  wheel_options.vertical_sigma_m_s = non_holonomic_sigma_m_s;
  sensors::ImuPreintegration pim(options_.imu.noise, preintegration, s.b_g, s.b_a);
  int64_t integrated_to_ns = s.t_ns;
  for (int i : used) {
    const sensors::WheelSample& w = wheel[static_cast<size_t>(i)];
    pim.Integrate(imu_, integrated_to_ns, w.t_ns);
    integrated_to_ns = w.t_ns;
    factors::WheelMeasurement m;
    m.left_rad_s = w.left_rad_s;
    m.right_rad_s = w.right_rad_s;
    // Eq. SW10: the mean gyro over the span around the wheel sample.
    const int64_t half_span_ns = SecondsToNs(0.5 * options_.wheel_gyro_mean_span_s);
    const sensors::GyroMean gyro =
        sensors::MeanGyro(imu_, w.t_ns - half_span_ns, w.t_ns + half_span_ns);
    m.gyro_rad_s = gyro.samples > 0 ? gyro.rate_rad_s
                                    : sensors::InterpolateImu(imu_, w.t_ns).gyro_rad_s;
    AttachedFactor f;
    f.cost = std::make_unique<internal::PropagatedWheelFactor>(
        pim, m, wheel_options, options_.wheel.noise_rad_s,
        gyro_sample_sigma_rad_s / std::sqrt(std::max(1, gyro.samples)));
    f.loss = wheel_loss_.get();
    f.linearized_per_pass = "a wheel factor";
    f.blocks = {s.q_W_I.coeffs().data(), s.v_W_I.data(), s.b_g.data(), s.b_a.data()};
    for (double* b : {c.q_I_V.coeffs().data(), c.p_I_V.data(), &c.wheel_radius_left_m,
                      &c.wheel_radius_right_m, &c.track_width_m}) {
      f.blocks.push_back(b);
    }
    from->factors.push_back(std::move(f));
  }

  // GNSS fixes of (t_from, t_end].
  sensors::ImuPreintegration gnss_pim(options_.imu.noise, preintegration, s.b_g, s.b_a);
  integrated_to_ns = s.t_ns;
  while (!gnss_.empty() && gnss_.front().t_ns <= t_end_ns) {
    const GnssPosition g = gnss_.front();
    gnss_.pop_front();
    gnss_pim.Integrate(imu_, integrated_to_ns, g.t_ns);
    integrated_to_ns = g.t_ns;
    factors::GnssMeasurement m;
    m.p_W_A = g.p_W_A;
    m.sigma_enu_m = g.sigma_enu_m;
    AttachedFactor f;
    f.cost.reset(internal::PropagatedGnssResidual::Create(gnss_pim, m));
    f.loss = gnss_loss_.get();
    f.linearized_per_pass = "a GNSS factor";
    f.blocks = StateBlocks(&s);
    f.blocks.push_back(c.p_I_A.data());
    from->factors.push_back(std::move(f));
  }
}

// The IMU factors' preintegrations follow their start keyframe's bias estimate (re-integrated
// when it moved beyond the PreintegrationOptions thresholds, Eq. F7 otherwise).
void SlidingWindowEstimator::RelinearizeImuFactors() {
  for (size_t k = 1; k < window_.size(); ++k) {
    const SlidingWindowState& from = window_[k - 1]->state;
    window_[k]->imu_from_previous->ReintegrateIfNeeded(from.b_g, from.b_a);
  }
}

void SlidingWindowEstimator::DropOldest(std::unique_ptr<MarginalizationPrior> prior) {
  prior_ = std::move(prior);
  marginalized_.push_back(window_.front()->state);
  WindowKeyframe& dropped = *window_.front();
  const int dropped_id = dropped.id;
  // Pairs with the dropped sweep are in the prior now, as are the dropped sweep's own.
  for (internal::SweepPointGroup& group : dropped.point_groups) terms_pool_->Retire(&group);
  spare_tried_at_ = std::move(dropped.tried_at);
  window_.pop_front();
  for (auto& kf : window_) terms_pool_->RetireGroupsOf(&kf->point_groups, dropped_id);
  window_.front()->imu_from_previous.reset();
  ++counters_.marginalizations;
}

// Keeps the IMU samples from the last one at or before the oldest keyframe on: the IMU
// factors and the sweeps' motion tables integrate from there.
void SlidingWindowEstimator::TrimImuBuffer() {
  const int64_t oldest_ns = window_.front()->state.t_ns;
  auto first_after = std::upper_bound(
      imu_.begin(), imu_.end(), oldest_ns,
      [](int64_t t, const sensors::ImuSample& s) { return t < s.t_ns; });
  if (first_after - imu_.begin() > 1) imu_.erase(imu_.begin(), first_after - 1);
}

// ---------------------------------------------------------------------------------------------
// Read access.

const SlidingWindowState& SlidingWindowEstimator::latest_state() const {
  return window_.back()->state;
}

int SlidingWindowEstimator::window_size() const { return static_cast<int>(window_.size()); }

std::vector<SlidingWindowState> SlidingWindowEstimator::Trajectory() const {
  std::vector<SlidingWindowState> out = marginalized_;
  for (const auto& kf : window_) out.push_back(kf->state);
  return out;
}

}  // namespace estimation
}  // namespace autocal
