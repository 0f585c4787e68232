#include "autocal/estimation/sliding_window.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/factors/prior_factors.h"
#include "estimation/sliding_window_internal.h"

namespace autocal {
namespace estimation {

using internal::AttachedFactor;
using internal::StateBlocks;

namespace {

constexpr int64_t kNoStamp = std::numeric_limits<int64_t>::min();

// q and mean: quaternions [x, y, z, w]; one sigma per tangent axis.
AttachedFactor QuaternionPrior(double* q, const double* mean, const Eigen::Vector3d& sigma_rad,
                               ceres::LossFunction* loss) {
  AttachedFactor f;
  f.cost = std::make_unique<factors::QuaternionPriorFactor>(
      Eigen::Map<const Eigen::Quaterniond>(mean).normalized(),
      Eigen::Matrix3d(sigma_rad.cwiseInverse().asDiagonal()));
  f.loss = loss;
  f.blocks = {q};
  return f;
}

AttachedFactor VectorPrior(double* x, const double* mean, const Eigen::VectorXd& sigma,
                           ceres::LossFunction* loss) {
  AttachedFactor f;
  f.cost = std::make_unique<factors::VectorPriorFactor>(
      Eigen::Map<const Eigen::VectorXd>(mean, sigma.size()),
      Eigen::MatrixXd(sigma.cwiseInverse().asDiagonal()));
  f.loss = loss;
  f.blocks = {x};
  return f;
}

bool AllFinite(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return a.allFinite() && b.allFinite();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The public API forwards to the implementation.

SlidingWindowEstimator::SlidingWindowEstimator(const SlidingWindowOptions& options,
                                               const sensors::Calibration& initial_calibration,
                                               const SlidingWindowState& initial_state)
    : impl_(std::make_unique<Impl>(options, initial_calibration, initial_state)) {}
SlidingWindowEstimator::~SlidingWindowEstimator() = default;

bool SlidingWindowEstimator::AddImu(const sensors::ImuSample& sample) {
  impl_->RequireUsable();
  return impl_->AddImu(sample);
}
bool SlidingWindowEstimator::AddWheel(const sensors::WheelSample& sample) {
  impl_->RequireUsable();
  return impl_->AddWheel(sample);
}

bool SlidingWindowEstimator::AddWheelSpeeds(const sensors::WheelSpeedSample& sample) {
  impl_->RequireUsable();
  return impl_->AddWheelSpeeds(sample);
}

bool SlidingWindowEstimator::AddOdometry(const sensors::OdometrySample& sample) {
  impl_->RequireUsable();
  return impl_->AddOdometry(sample);
}
bool SlidingWindowEstimator::AddGnss(const sensors::GnssFix& fix) {
  impl_->RequireUsable();
  return impl_->AddGnss(fix);
}
bool SlidingWindowEstimator::AddGnss(const GnssPosition& position) {
  impl_->RequireUsable();
  return impl_->AddGnss(position);
}
bool SlidingWindowEstimator::AddSweep(lidar::LidarSweep sweep) {
  impl_->RequireUsable();
  return impl_->AddSweep(std::move(sweep));
}
bool SlidingWindowEstimator::AddKeyframeAt(int64_t t_ns) {
  impl_->RequireUsable();
  return impl_->AddKeyframeAt(t_ns);
}
const SlidingWindowState& SlidingWindowEstimator::latest_state() const {
  return impl_->latest_state();
}
std::vector<SlidingWindowState> SlidingWindowEstimator::Trajectory() const {
  return impl_->Trajectory();
}
std::vector<SlidingWindowState> SlidingWindowEstimator::SmoothedTrajectory() const {
  return impl_->SmoothedTrajectory(impl_->calibration());
}
std::vector<SlidingWindowState> SlidingWindowEstimator::SmoothedTrajectory(
    const sensors::Calibration& calibration) const {
  return impl_->SmoothedTrajectory(calibration);
}
const sensors::Calibration& SlidingWindowEstimator::calibration() const {
  return impl_->calibration();
}
CalibrationCovariance SlidingWindowEstimator::ComputeCalibrationCovariance(
    double min_reciprocal_condition_number) {
  impl_->RequireUsable();
  return impl_->ComputeCalibrationCovariance(min_reciprocal_condition_number);
}
std::vector<FixedDirectionMove> SlidingWindowEstimator::FixedDirectionsTheStreamMoves(
    std::vector<EstimatedBlock> fixed, double max_sigmas) {
  impl_->RequireUsable();
  return impl_->FixedDirectionsTheStreamMoves(std::move(fixed), max_sigmas);
}
int SlidingWindowEstimator::window_size() const { return impl_->window_size(); }
int SlidingWindowEstimator::pending_sweeps() const { return impl_->pending_sweeps(); }
bool SlidingWindowEstimator::has_marginalization_prior() const {
  return impl_->has_marginalization_prior();
}
const SlidingWindowCounters& SlidingWindowEstimator::counters() const { return impl_->counters(); }
const SlidingWindowUpdateTiming& SlidingWindowEstimator::last_update_timing() const {
  return impl_->last_update_timing();
}
int SlidingWindowEstimator::last_associated_points() const {
  return impl_->last_associated_points();
}
double SlidingWindowEstimator::last_point_rms_m() const { return impl_->last_point_rms_m(); }
GnssNoiseFromResiduals SlidingWindowEstimator::gnss_noise() const { return impl_->gnss_noise(); }
GnssStdScale SlidingWindowEstimator::gnss_std_scale() const { return impl_->gnss_std_scale(); }
GnssStdScale SlidingWindowEstimator::largest_gnss_std_scale() const {
  return impl_->largest_gnss_std_scale();
}

// ---------------------------------------------------------------------------------------------
// The implementation: construction, streaming input and one update.

SlidingWindowEstimator::Impl::Impl(const SlidingWindowOptions& options,
                                   const sensors::Calibration& initial_calibration,
                                   const SlidingWindowState& initial_state)
    : options_(options),
      g_W_(0.0, 0.0, -options.imu.gravity_m_s2),
      calibration_(initial_calibration),
      newest_wheel_ns_(kNoStamp),
      newest_gnss_ns_(kNoStamp),
      newest_sweep_ns_(kNoStamp),
      newest_time_ns_(kNoStamp),
      pairing_(internal::PairingWithinWindow(options), options.window_pairing, options.loss.lidar,
               options.num_threads) {
  internal::CheckOptions(options_);
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
  if (options_.initial_state_covariance) {
    // Sigma = L L^T, so Sigma^-1 = L^-T L^-1 and the square root of the information is L^-1.
    const Eigen::Matrix<double, 15, 15> l = options_.initial_state_covariance->llt().matrixL();
    prior.sqrt_information =
        l.triangularView<Eigen::Lower>().solve(Eigen::Matrix<double, 15, 15>::Identity());
  } else {
    prior.sqrt_information = s.InStatePriorOrder().cwiseInverse().asDiagonal();
  }
  AttachedFactor state_prior;
  state_prior.cost = std::make_unique<factors::StatePriorFactor>(prior);
  state_prior.loss = prior_loss_.get();
  state_prior.blocks = StateBlocks(&kf->state);
  kf->factors.push_back(std::move(state_prior));
  window_.push_back(std::move(kf));

  AddCalibrationPriors(initial_calibration);
}

// Calibration priors (never marginalized: they touch no keyframe), one per estimated block.
void SlidingWindowEstimator::Impl::AddCalibrationPriors(
    const sensors::Calibration& initial_calibration) {
  const SlidingWindowCalibrationPrior& c = options_.calibration_prior;
  const sensors::Calibration& mean = c.mean ? *c.mean : initial_calibration;
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    if (!Estimated(info.id, options_.estimate)) continue;
    double* x = info.values(&calibration_);
    const double* m = info.const_values(mean);
    const Eigen::VectorXd sigma = PriorSigmasOf(info.id, c);
    calibration_priors_.push_back(info.manifold == sensors::BlockManifold::kRightQuaternion
                                      ? QuaternionPrior(x, m, sigma * kDegToRad, prior_loss_.get())
                                      : VectorPrior(x, m, sigma, prior_loss_.get()));
  }
}

bool SlidingWindowEstimator::Impl::AddImu(const sensors::ImuSample& sample) {
  if (!AllFinite(sample.gyro_rad_s, sample.accel_m_s2)) {
    throw Error("SlidingWindowEstimator::AddImu: non-finite sample at t_ns " +
                std::to_string(sample.t_ns));
  }
  if (!imu_.empty() && sample.t_ns <= imu_.back().t_ns) {
    ++counters_.out_of_order;
    return false;
  }
  if (imu_.empty() && sample.t_ns > window_.front()->state.t_ns) {
    throw Error(
        "SlidingWindowEstimator::AddImu: the IMU stream must start at or before the "
        "initial state's time (first sample at t_ns " +
        std::to_string(sample.t_ns) + ", initial state at " +
        std::to_string(window_.front()->state.t_ns) + ")");
  }
  imu_.push_back(sample);
  ++counters_.imu_accepted;
  ProcessCoveredSweeps();
  ProcessCoveredTimes();
  return true;
}

bool SlidingWindowEstimator::Impl::AddWheel(const sensors::WheelSample& sample) {
  if (!std::isfinite(sample.left_rad_s) || !std::isfinite(sample.right_rad_s)) {
    throw Error("SlidingWindowEstimator::AddWheel: non-finite rates at t_ns " +
                std::to_string(sample.t_ns));
  }
  if (!AcceptWheelStamp(sample.t_ns)) return false;
  wheel_.push_back(sample);
  ++counters_.wheel_accepted;
  return true;
}

bool SlidingWindowEstimator::Impl::AcceptWheelStamp(int64_t t_ns) {
  if (t_ns <= newest_wheel_ns_) {
    ++counters_.out_of_order;
    return false;
  }
  newest_wheel_ns_ = t_ns;
  if (t_ns <= latest_state().t_ns) {
    ++counters_.late;
    return false;
  }
  return true;
}

bool SlidingWindowEstimator::Impl::AddWheelSpeeds(const sensors::WheelSpeedSample& sample) {
  if (!std::isfinite(sample.left_m_s) || !std::isfinite(sample.right_m_s)) {
    throw Error("SlidingWindowEstimator::AddWheelSpeeds: non-finite speeds at t_ns " +
                std::to_string(sample.t_ns));
  }
  if (!AcceptWheelStamp(sample.t_ns)) return false;
  wheel_speeds_.push_back(sample);
  ++counters_.wheel_accepted;
  return true;
}

bool SlidingWindowEstimator::Impl::AddOdometry(const sensors::OdometrySample& sample) {
  if (!std::isfinite(sample.speed_m_s) || !std::isfinite(sample.yaw_rate_rad_s)) {
    throw Error("SlidingWindowEstimator::AddOdometry: non-finite speed or yaw rate at t_ns " +
                std::to_string(sample.t_ns));
  }
  if (!options_.wheel.controller_track_m || !(*options_.wheel.controller_track_m > 0.0)) {
    throw Error("SlidingWindowEstimator::AddOdometry: options.wheel.controller_track_m is not set");
  }
  if (!AcceptWheelStamp(sample.t_ns)) return false;
  odometry_.push_back(sample);
  ++counters_.wheel_accepted;
  return true;
}

bool SlidingWindowEstimator::Impl::AddGnss(const sensors::GnssFix& fix) {
  if (!enu_) enu_.emplace(fix.lat_deg, fix.lon_deg, fix.alt_m);  // W at the first fix
  GnssPosition position;
  position.t_ns = fix.t_ns;
  position.p_W_A = enu_->ToEnu(fix);
  position.sigma_enu_m = fix.std_enu_m;
  return AddGnss(position);
}

bool SlidingWindowEstimator::Impl::AddGnss(const GnssPosition& position) {
  if (!position.p_W_A.allFinite() || !position.sigma_enu_m.allFinite() ||
      !(position.sigma_enu_m.minCoeff() > 0.0)) {
    throw Error(
        "SlidingWindowEstimator::AddGnss: non-finite position or non-positive sigma at "
        "t_ns " +
        std::to_string(position.t_ns));
  }
  if (position.t_ns <= newest_gnss_ns_) {
    ++counters_.out_of_order;
    return false;
  }
  newest_gnss_ns_ = position.t_ns;
  if (position.t_ns <= latest_state().t_ns) {
    ++counters_.late;
    ++counters_.late_gnss;
    return false;
  }
  gnss_.push_back(position);
  ++counters_.gnss_accepted;
  return true;
}

bool SlidingWindowEstimator::Impl::AddSweep(lidar::LidarSweep sweep) {
  UseKeyframeSource(KeyframeSource::kSweeps);
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
  SpannedSweep spanned{std::move(sweep), {}};
  spanned.span = SpanOf(spanned.sweep);
  if (TooCloseToNewestKeyframe(KeyframeTimeOf(spanned))) {
    ++counters_.late;
    return false;
  }
  pending_sweeps_.push_back(std::move(spanned));
  ++counters_.sweeps_accepted;
  ProcessCoveredSweeps();
  return true;
}

bool SlidingWindowEstimator::Impl::AddKeyframeAt(int64_t t_ns) {
  UseKeyframeSource(KeyframeSource::kTimes);
  if (t_ns <= newest_time_ns_) {
    ++counters_.out_of_order;
    return false;
  }
  newest_time_ns_ = t_ns;
  // Each time waiting for the IMU becomes a keyframe: the newest of them counts as the newest
  // keyframe.
  if (TooCloseToNewestKeyframe(t_ns) ||
      (!pending_times_.empty() && t_ns - pending_times_.back() < MinKeyframeIntervalNs())) {
    ++counters_.late;
    return false;
  }
  pending_times_.push_back(t_ns);
  ++counters_.keyframe_times_accepted;
  ProcessCoveredTimes();
  return true;
}

void SlidingWindowEstimator::Impl::UseKeyframeSource(KeyframeSource source) {
  if (keyframe_source_ == source) return;
  if (keyframe_source_ != KeyframeSource::kUndecided) {
    throw Error(source == KeyframeSource::kSweeps
                    ? "SlidingWindowEstimator::AddSweep: this window takes its keyframes from "
                      "AddKeyframeAt, not from sweeps"
                    : "SlidingWindowEstimator::AddKeyframeAt: this window takes its keyframes "
                      "from sweeps, not from AddKeyframeAt");
  }
  keyframe_source_ = source;
  if (source != KeyframeSource::kTimes) return;
  // No point rows: the LiDAR blocks stay where they are. No update has run yet, so the
  // calibration is still the initial one the priors are rebuilt with.
  options_.estimate.extrinsic_rotation = false;
  options_.estimate.extrinsic_translation = false;
  options_.estimate.time_offset = false;
  calibration_priors_.clear();
  AddCalibrationPriors(calibration_);
}

int64_t SlidingWindowEstimator::Impl::KeyframeTimeOf(const SpannedSweep& sweep) const {
  return KeyframeTime(sweep.sweep.t_ns, sweep.span, calibration_.time_offset_lidar_imu_s);
}

int64_t SlidingWindowEstimator::Impl::MinKeyframeIntervalNs() const {
  return std::max<int64_t>(1, SecondsToNs(options_.min_keyframe_interval_s));
}

bool SlidingWindowEstimator::Impl::TooCloseToNewestKeyframe(int64_t t_ns) const {
  return t_ns - latest_state().t_ns < MinKeyframeIntervalNs();
}

bool SlidingWindowEstimator::Impl::NoImuSinceNewestKeyframe(int64_t t_ns) const {
  return !sensors::ImuSampleBetween(imu_, latest_state().t_ns, t_ns);
}

void SlidingWindowEstimator::Impl::ProcessCoveredSweeps() {
  while (!pending_sweeps_.empty() && !imu_.empty()) {
    const SpannedSweep& next = pending_sweeps_.front();
    const int64_t needed_ns =
        SweepImuInterval(next.sweep.t_ns, next.span, calibration_.time_offset_lidar_imu_s).end_ns +
        SecondsToNs(options_.imu_coverage_margin_s);
    if (imu_.back().t_ns < needed_ns) return;
    SpannedSweep covered = std::move(pending_sweeps_.front());
    pending_sweeps_.pop_front();
    // The offset estimate may have moved since the sweep arrived.
    const int64_t t_ns = KeyframeTimeOf(covered);
    if (TooCloseToNewestKeyframe(t_ns)) {
      ++counters_.late;
    } else if (NoImuSinceNewestKeyframe(t_ns)) {
      ++counters_.without_imu;
    } else {
      Update(t_ns, std::move(covered));
    }
  }
}

void SlidingWindowEstimator::Impl::ProcessCoveredTimes() {
  while (!pending_times_.empty() && !imu_.empty() &&
         imu_.back().t_ns >= pending_times_.front() + SecondsToNs(options_.imu_coverage_margin_s)) {
    const int64_t t_ns = pending_times_.front();
    pending_times_.pop_front();
    if (NoImuSinceNewestKeyframe(t_ns)) {
      ++counters_.without_imu;
    } else {
      Update(t_ns, std::nullopt);
    }
  }
}

void SlidingWindowEstimator::Impl::RequireUsable() const {
  if (failed_update_.empty()) return;
  throw Error(
      "SlidingWindowEstimator: an earlier update failed and left the window between two states, "
      "so it cannot go on (start a new estimator): " +
      failed_update_);
}

void SlidingWindowEstimator::Impl::Update(int64_t t_ns, std::optional<SpannedSweep> sweep) {
  try {
    UpdateWindow(t_ns, std::move(sweep));
  } catch (const std::exception& e) {
    failed_update_ = e.what();
    throw;
  }
}

void SlidingWindowEstimator::Impl::UpdateWindow(int64_t t_ns, std::optional<SpannedSweep> sweep) {
  const auto start = std::chrono::steady_clock::now();
  timing_ = SlidingWindowUpdateTiming();
  AddKeyframe(t_ns, std::move(sweep));
  RelinearizeImuFactors();

  if (keyframe_source_ == KeyframeSource::kSweeps) {
    const auto association_start = std::chrono::steady_clock::now();
    AssociatePoints();
    timing_.association_s = SecondsSince(association_start);
  }

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
    RecordGnssRowsOfOldest();
    std::unique_ptr<MarginalizationPrior> prior = MarginalizeOldest(build.get());
    std::unique_ptr<MarginalizationPrior> tested = CarryTestedBlocks(build.get(), prior != nullptr);
    build.reset();  // the problem refers to the factors about to be dropped
    tested_prior_ = std::move(tested);
    DropOldest(std::move(prior));
    timing_.marginalization_s = SecondsSince(marginalization_start);
  }
  TrimImuBuffer();
  recent_q_I_L_.push_back(calibration_.q_I_L);
  while (static_cast<int>(recent_q_I_L_.size()) > options_.window_size) recent_q_I_L_.pop_front();
  ++counters_.updates;
  timing_.total_s = SecondsSince(start);
}

std::unique_ptr<MarginalizationPrior> SlidingWindowEstimator::Impl::CarryTestedBlocks(
    ProblemBuild* build, bool main_prior) {
  if (options_.tested_fixed_blocks.empty() || !untested_reason_.empty()) return nullptr;
  try {
    std::unique_ptr<MarginalizationPrior> tested = MarginalizeOldestWithTestedBlocks(build);
    if (main_prior && tested == nullptr) {
      untested_reason_ = "their marginalization kept no information where the window's did";
    }
    return tested;
  } catch (const Error& e) {
    untested_reason_ = e.what();
  }
  return nullptr;
}

std::vector<SlidingWindowState> SlidingWindowEstimator::Impl::Trajectory() const {
  std::vector<SlidingWindowState> out = marginalized_;
  for (const auto& kf : window_) out.push_back(kf->state);
  return out;
}

}  // namespace estimation
}  // namespace autocal
