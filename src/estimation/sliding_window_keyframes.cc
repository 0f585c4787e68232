// The sliding window's keyframes (docs/sliding_window.md, "One update" steps 1-2 and 5):
// a new keyframe predicted with the IMU, its chosen points, the wheel and GNSS factors of the
// interval before it, and the oldest keyframe dropped after its marginalization.
#include <algorithm>
#include <cmath>
#include <utility>

#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/factors/planar_rotation_factor.h"
#include "estimation/point_selection.h"
#include "estimation/sliding_window_internal.h"

namespace autocal {
namespace estimation {

using internal::AttachedFactor;
using internal::StateBlocks;

void SlidingWindowEstimator::Impl::AddKeyframe(int64_t t_ns, std::optional<SpannedSweep> sweep) {
  WindowKeyframe& previous = *window_.back();
  auto kf = std::make_unique<WindowKeyframe>();
  kf->pairing.tried_at = std::move(spare_tried_at_);  // overwritten before use
  kf->id = next_keyframe_id_++;
  kf->state.t_ns = t_ns;

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
  if (sweep) SetSweepPoints(std::move(*sweep), kf.get());

  AttachIntervalMeasurements(&previous, kf->state.t_ns);
  window_.push_back(std::move(kf));
}

void SlidingWindowEstimator::Impl::SetSweepPoints(SpannedSweep spanned, WindowKeyframe* kf) const {
  const lidar::LidarSweep& sweep = spanned.sweep;
  internal::SweepSelection selection = internal::SelectSweepPoints(sweep.cloud, options_.pairing);
  kf->map_points = std::move(selection.map_points);
  internal::ResidualPoints& res = kf->residuals;
  res.indices = std::move(selection.residual_points);
  const size_t num_residuals = res.size();
  res.p_L.resize(3, static_cast<Eigen::Index>(num_residuals));
  res.time_s.resize(num_residuals);
  res.ranges_m.resize(num_residuals);
  for (size_t r = 0; r < num_residuals; ++r) {
    const int i = res.indices[r];
    res.p_L.col(static_cast<Eigen::Index>(r)) = sweep.cloud.points.col(i);
    res.time_s[r] = sweep.cloud.time_s(i);
    res.ranges_m[r] = sweep.cloud.points.col(i).norm();
    res.max_range_m = std::max(res.max_range_m, res.ranges_m[r]);
  }
  kf->sweep_span = spanned.span;
  kf->sweep = std::move(spanned.sweep);
}

// 1-sigma of one gyro sample at the stated IMU rate.
double SlidingWindowEstimator::Impl::GyroSampleSigma() const {
  return options_.imu.noise.GyroSampleSigmaRadS(options_.imu.noise.update_rate_hz);
}

// 1-sigma of the mean of gyro.samples samples (at least one).
double SlidingWindowEstimator::Impl::GyroMeanSigma(const sensors::GyroMean& gyro) const {
  return GyroSampleSigma() / std::sqrt(std::max(1, gyro.samples));
}

// The body rate the wheel rows take at t_ns, their sigmas and the 1-sigma of its part the
// yaw-rate row reads: the gyro mean (GyroAround, GyroMeanSigma) or, with the log's spread of
// rates, the rate given that mean (Eq. K14) with its remaining error through the lever arm
// (Eq. K13, at the current mount and lever arm).
SlidingWindowEstimator::Impl::RowBodyRate SlidingWindowEstimator::Impl::BodyRateAround(
    int64_t t_ns, const factors::WheelFactorOptions& rows) const {
  const sensors::GyroMean gyro = GyroAround(t_ns);
  const double sigma = GyroMeanSigma(gyro);
  const std::optional<sensors::BodyRatePrior>& prior = options_.wheel_rows.body_rate_prior;
  if (!prior) return {gyro.rate_rad_s, rows, sigma};
  const sensors::BodyRate rate = prior->Condition({gyro.rate_rad_s, sigma * sigma});
  // The yaw part is the yaw-rate row's gyro sigma, floored: a log that never turns leaves no
  // yaw error, and the rows need a positive sigma.
  const factors::WheelFactorOptions with_lever =
      WithLeverArmRateCovariance(rows, rate.covariance, calibration_.q_I_V, calibration_.p_I_V);
  const double yaw_variance =
      YawRowRateVariance(rate.covariance, calibration_.q_I_V, rows.yaw_axis_I);
  return {rate.rate_rad_s, with_lever, std::sqrt(std::max(1e-24, yaw_variance)),
          with_lever.speed_sigma_m_s * with_lever.speed_sigma_m_s -
              rows.speed_sigma_m_s * rows.speed_sigma_m_s};
}

void SlidingWindowEstimator::Impl::UpdateTurningAxis(const WindowKeyframe& from) {
  const double max_error_deg = options_.wheel_rows.max_turning_axis_error_deg;
  if (!(max_error_deg > 0.0)) return;
  turning_rates_.Add(BodyRateAround(from.state.t_ns, factors::WheelFactorOptions()).rate_rad_s);
  if (const std::optional<Eigen::Vector3d> axis = turning_rates_.Axis(
          calibration_.q_I_V * Eigen::Vector3d::UnitZ(), max_error_deg * kDegToRad)) {
    yaw_axis_I_ = *axis;
  }
}

// A wheel-row factor (any form) on the keyframe's q_W_I, v_W_I, b_g, b_a and the calibration's
// `blocks`, linearized per pass under the name `what`.
internal::AttachedFactor SlidingWindowEstimator::Impl::WheelRowFactor(
    ceres::CostFunction* cost, SlidingWindowState* s, std::initializer_list<double*> blocks,
    const char* what) const {
  internal::AttachedFactor f;
  f.cost.reset(cost);
  f.loss = wheel_loss_.get();
  f.linearized_per_pass = what;
  f.blocks = {s->q_W_I.coeffs().data(), s->v_W_I.data(), s->b_g.data(), s->b_a.data()};
  f.blocks.insert(f.blocks.end(), blocks);
  return f;
}

// The mean gyro over the span around t_ns (wheel_rows.gyro_mean_span_s) and how many samples
// it averaged; the interpolated sample when the span holds none.
sensors::GyroMean SlidingWindowEstimator::Impl::GyroAround(int64_t t_ns) const {
  return sensors::GyroAround(imu_, t_ns, SecondsToNs(0.5 * options_.wheel_rows.gyro_mean_span_s));
}

// The correlated-error scaling of the non-holonomic rows at the spacing of `used` samples over
// (t_from, t_end].
double SlidingWindowEstimator::Impl::NonHolonomicScale(size_t used, int64_t t_from_ns,
                                                       int64_t t_end_ns) const {
  return NonHolonomicSigmaScale(
      options_.wheel_rows.non_holonomic_correlation_s,
      used == 0 ? 0.0 : NsToSeconds(t_end_ns - t_from_ns) / static_cast<double>(used));
}

// The wheel rows' options with the non-holonomic sigmas times `scale`: the lateral row's the
// rear axle's slip driving straight (WheelConfig, Eq. K6c; its turning part per sample in
// AttachPropagated), the vertical row's wheel_rows.vertical_sigma_m_s.
factors::WheelFactorOptions SlidingWindowEstimator::Impl::NonHolonomicRows(
    factors::WheelFactorOptions options, double scale) const {
  options.non_holonomic = options_.wheel_rows.non_holonomic;
  options.lateral_sigma_m_s = options_.wheel.lateral_slip_sigma_m_s * scale;
  options.vertical_sigma_m_s = options_.wheel_rows.vertical_sigma_m_s * scale;
  return options;
}

// Samples of `queue` up to t_end_ns, taken out of it and evenly thinned.
template <typename Sample>
std::vector<Sample> SlidingWindowEstimator::Impl::TakeThinned(std::deque<Sample>* queue,
                                                              int64_t t_end_ns) const {
  std::vector<Sample> taken;
  while (!queue->empty() && queue->front().t_ns <= t_end_ns) {
    taken.push_back(queue->front());
    queue->pop_front();
  }
  std::vector<int> all(taken.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  std::vector<Sample> used;
  for (int i : internal::Thin(all, options_.wheel_rows.max_samples_per_interval)) {
    used.push_back(taken[static_cast<size_t>(i)]);
  }
  return used;
}

// One factor per sample of `used` (taken over (from's time, t_end_ns]), at the state propagated
// from `from` to the sample's time: make(pim, sample, sample_rows) builds it from the
// preintegration up to there and the sample's rows: the form's `form_rows` with the
// non-holonomic rows (NonHolonomicRows, the lateral row's turning slip per sample), the body rate
// around the sample (BodyRateAround) and the propagated velocity's variances (Eq. W7) added, the
// speed row's to rows.speed_sigma_m_s when the form whitens that row by it
// (`speed_row_by_options`), else to speed_variance_m2_s2.
template <typename Sample, typename Make>
void SlidingWindowEstimator::Impl::AttachPropagated(WindowKeyframe* from,
                                                    const std::vector<Sample>& used,
                                                    int64_t t_end_ns,
                                                    const factors::WheelFactorOptions& form_rows,
                                                    bool speed_row_by_options, Make make) const {
  const SlidingWindowState& s = from->state;
  const double slip_scale = NonHolonomicScale(used.size(), s.t_ns, t_end_ns);
  const factors::WheelFactorOptions rows = NonHolonomicRows(form_rows, slip_scale);
  sensors::PreintegrationOptions preintegration;
  preintegration.gravity_m_s2 = options_.imu.gravity_m_s2;
  sensors::ImuPreintegration pim(options_.imu.noise, preintegration, s.b_g, s.b_a);
  factors::WheelFactorOptions about_axis = rows;
  about_axis.yaw_axis_I = yaw_axis_I_;
  const Eigen::Vector3d turning_axis_I = YawRowAxis(calibration_.q_I_V, yaw_axis_I_);
  int64_t integrated_to_ns = s.t_ns;
  for (const Sample& sample : used) {
    pim.Integrate(imu_, integrated_to_ns, sample.t_ns);
    integrated_to_ns = sample.t_ns;
    RowBodyRate sample_rows = BodyRateAround(sample.t_ns, about_axis);
    // The slip out of the sample's turn (Eq. K6c), scaled as the row's straight part.
    sample_rows.rows.lateral_sigma_m_s = std::hypot(
        sample_rows.rows.lateral_sigma_m_s,
        slip_scale * CorneringSlipMS(options_.wheel.cornering_compliance_rad_per_m_s2,
                                     s.v_W_I.norm(), sample_rows.rate_rad_s.dot(turning_axis_I)));
    const Eigen::Matrix3d velocity =
        internal::PropagatedVelocityCovariance(pim, s.q_W_I, s.v_W_I, calibration_.q_I_V);
    // The speed row's share goes to rows.speed_sigma_m_s only where the form whitens by it.
    Eigen::Matrix3d rows_velocity = velocity;
    if (!speed_row_by_options) {
      rows_velocity(0, 0) = 0.0;
      sample_rows.speed_variance_m2_s2 += velocity(0, 0);
    }
    sample_rows.rows = WithVelocityCovariance(sample_rows.rows, rows_velocity);
    from->factors.push_back(make(pim, sample, sample_rows));
  }
}

void SlidingWindowEstimator::Impl::AttachWheelFactors(WindowKeyframe* from, int64_t t_end_ns) {
  SlidingWindowState& s = from->state;
  sensors::Calibration& c = calibration_;
  const std::vector<sensors::WheelSample> used = TakeThinned(&wheel_, t_end_ns);
  AttachPropagated(
      from, used, t_end_ns,
      factors::WheelFactorOptions::FromEncoderNoise(
          options_.wheel, 0.5 * (c.wheel_radius_left_m + c.wheel_radius_right_m), c.track_width_m),
      false,
      [&](const sensors::ImuPreintegration& pim, const sensors::WheelSample& w,
          const RowBodyRate& gyro) {
        factors::WheelMeasurement m;
        m.left_rad_s = w.left_rad_s;
        m.right_rad_s = w.right_rad_s;
        m.gyro_rad_s = gyro.rate_rad_s;
        return WheelRowFactor(
            new internal::PropagatedWheelFactor(pim, m, gyro.rows, options_.wheel.noise_rad_s,
                                                gyro.yaw_sigma_rad_s, gyro.speed_variance_m2_s2),
            &s,
            {c.q_I_V.coeffs().data(), c.p_I_V.data(), &c.wheel_radius_left_m,
             &c.wheel_radius_right_m, &c.track_width_m},
            "a wheel factor");
      });
}

void SlidingWindowEstimator::Impl::AttachWheelSpeedFactors(WindowKeyframe* from, int64_t t_end_ns) {
  SlidingWindowState& s = from->state;
  sensors::Calibration& c = calibration_;
  const std::vector<sensors::WheelSpeedSample> used = TakeThinned(&wheel_speeds_, t_end_ns);
  AttachPropagated(
      from, used, t_end_ns,
      factors::WheelFactorOptions::FromWheelSpeedNoise(options_.wheel, c.track_width_m), false,
      [&](const sensors::ImuPreintegration& pim, const sensors::WheelSpeedSample& w,
          const RowBodyRate& gyro) {
        factors::WheelSpeedMeasurement m;
        m.left_m_s = w.left_m_s;
        m.right_m_s = w.right_m_s;
        m.gyro_rad_s = gyro.rate_rad_s;
        return WheelRowFactor(internal::PropagatedWheelSpeedResidual::Create(
                                  pim, m, gyro.rows, options_.wheel.noise_m_s, gyro.yaw_sigma_rad_s,
                                  gyro.speed_variance_m2_s2),
                              &s,
                              {c.q_I_V.coeffs().data(), c.p_I_V.data(), &c.wheel_speed_scale_left,
                               &c.wheel_speed_scale_right, &c.track_width_m},
                              "a wheel speed factor");
      });
}

void SlidingWindowEstimator::Impl::AttachOdometryFactors(WindowKeyframe* from, int64_t t_end_ns) {
  SlidingWindowState& s = from->state;
  sensors::Calibration& c = calibration_;
  const std::vector<sensors::OdometrySample> used = TakeThinned(&odometry_, t_end_ns);
  AttachPropagated(
      from, used, t_end_ns, factors::WheelFactorOptions::FromOdometryNoise(options_.wheel), true,
      [&](const sensors::ImuPreintegration& pim, const sensors::OdometrySample& o,
          const RowBodyRate& gyro) {
        factors::OdometryMeasurement m;
        m.speed_m_s = o.speed_m_s;
        m.yaw_rate_rad_s = o.yaw_rate_rad_s;
        m.controller_track_m = *options_.wheel.controller_track_m;
        m.gyro_rad_s = gyro.rate_rad_s;
        return WheelRowFactor(
            internal::PropagatedOdometryResidual::Create(pim, m, gyro.rows, gyro.yaw_sigma_rad_s),
            &s,
            {c.q_I_V.coeffs().data(), c.p_I_V.data(), &c.odometry_speed_scale,
             &c.effective_track_m},
            "an odometry factor");
      });
}

// The planar-rotation row (Eq. F27) of keyframe `from`, once the IMU covers the gyro span around
// it (the interval after it is attached when the next keyframe arrives).
void SlidingWindowEstimator::Impl::AttachPlanarRotationFactor(WindowKeyframe* from) {
  const double sigma = options_.wheel_rows.planar_rotation_sigma_rad_s;
  if (sigma == 0.0) return;
  factors::PlanarRotationMeasurement m;
  m.gyro_rad_s = GyroAround(from->state.t_ns).rate_rad_s;
  m.sigma_rad_s = sigma;
  AttachedFactor f;
  f.cost.reset(factors::PlanarRotationFactor::Create(m));
  f.loss = wheel_loss_.get();
  f.linearized_per_pass = "a planar-rotation factor";
  f.blocks = {from->state.b_g.data(), calibration_.q_I_V.coeffs().data()};
  from->factors.push_back(std::move(f));
}

void SlidingWindowEstimator::Impl::AttachIntervalMeasurements(WindowKeyframe* from,
                                                              int64_t t_end_ns) {
  sensors::PreintegrationOptions preintegration;
  preintegration.gravity_m_s2 = options_.imu.gravity_m_s2;
  SlidingWindowState& s = from->state;
  sensors::Calibration& c = calibration_;

  UpdateTurningAxis(*from);
  AttachWheelFactors(from, t_end_ns);
  AttachWheelSpeedFactors(from, t_end_ns);
  AttachOdometryFactors(from, t_end_ns);
  AttachPlanarRotationFactor(from);

  // GNSS fixes of (t_from, t_end].
  sensors::ImuPreintegration gnss_pim(options_.imu.noise, preintegration, s.b_g, s.b_a);
  int64_t integrated_to_ns = s.t_ns;
  while (!gnss_.empty() && gnss_.front().t_ns <= t_end_ns) {
    const GnssPosition g = gnss_.front();
    gnss_.pop_front();
    gnss_pim.Integrate(imu_, integrated_to_ns, g.t_ns);
    integrated_to_ns = g.t_ns;
    factors::GnssMeasurement m;
    m.p_W_A = g.p_W_A;
    const GnssStdScale scale = gnss_std_scale();
    m.sigma_enu_m = scale.Applied(g.sigma_enu_m);
    if (!scale.IsOne()) ++counters_.gnss_scaled;
    largest_gnss_std_scale_.horizontal =
        std::max(largest_gnss_std_scale_.horizontal, scale.horizontal);
    largest_gnss_std_scale_.vertical = std::max(largest_gnss_std_scale_.vertical, scale.vertical);
    AttachedFactor f;
    f.gnss_std_scale = scale;
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
void SlidingWindowEstimator::Impl::RelinearizeImuFactors() {
  for (size_t k = 1; k < window_.size(); ++k) {
    const SlidingWindowState& from = window_[k - 1]->state;
    window_[k]->imu_from_previous->ReintegrateIfNeeded(from.b_g, from.b_a);
  }
}

void SlidingWindowEstimator::Impl::DropOldest(std::unique_ptr<MarginalizationPrior> prior) {
  prior_ = std::move(prior);
  marginalized_.push_back(window_.front()->state);
  WindowKeyframe& dropped = *window_.front();
  const int dropped_id = dropped.id;
  // Pairs with the dropped sweep are in the prior now, as are the dropped sweep's own.
  for (internal::SweepPointGroup& group : dropped.point_groups) pairing_.pool().Retire(&group);
  spare_tried_at_ = std::move(dropped.pairing.tried_at);
  window_.pop_front();
  for (auto& kf : window_) pairing_.pool().RetireGroupsOf(&kf->point_groups, dropped_id);
  window_.front()->imu_from_previous.reset();
  ++counters_.marginalizations;
}

GnssStdScale SlidingWindowEstimator::Impl::gnss_std_scale() const {
  const GnssNoiseFromResiduals own = gnss_noise();
  const auto judged = [](const GnssAxisNoise& axis, double before) {
    return axis.rows >= kMinGnssNoiseRows ? axis.scale : before;
  };
  return {judged(own.horizontal, options_.gnss_std_scale.horizontal),
          judged(own.vertical, options_.gnss_std_scale.vertical)};
}

void SlidingWindowEstimator::Impl::RecordGnssRowsOfOldest() {
  if (!options_.gnss_noise_from_residuals) return;
  double rows[3];  // east, north, up, whitened by the std the fix was attached with
  for (const internal::AttachedFactor& f : window_.front()->factors) {
    if (!f.gnss_std_scale || f.cost->num_residuals() != 3) continue;
    if (!f.cost->Evaluate(f.blocks.data(), rows, nullptr)) continue;
    const GnssStdScale& scale = *f.gnss_std_scale;
    gnss_rows_.AddHorizontal(rows[0] * scale.horizontal);
    gnss_rows_.AddHorizontal(rows[1] * scale.horizontal);
    gnss_rows_.AddVertical(rows[2] * scale.vertical);
  }
}

// Keeps the IMU samples from the last one at or before the oldest keyframe or its sweep's first
// point (less imu_coverage_margin_s, room for the offset to move) on: the IMU factors and the
// sweeps' motion tables integrate from there.
void SlidingWindowEstimator::Impl::TrimImuBuffer() {
  const WindowKeyframe& oldest = *window_.front();
  int64_t oldest_ns = oldest.state.t_ns;
  if (oldest.sweep) {
    const ImuInterval points = SweepImuInterval(oldest.sweep->t_ns, oldest.sweep_span,
                                                calibration_.time_offset_lidar_imu_s);
    oldest_ns = std::min(oldest_ns, points.begin_ns - SecondsToNs(options_.imu_coverage_margin_s));
  }
  auto first_after =
      std::upper_bound(imu_.begin(), imu_.end(), oldest_ns,
                       [](int64_t t, const sensors::ImuSample& s) { return t < s.t_ns; });
  if (first_after - imu_.begin() > 1) imu_.erase(imu_.begin(), first_after - 1);
}

}  // namespace estimation
}  // namespace autocal
