// The sliding window's keyframes (docs/sliding_window.md, "One update" steps 1-2 and 5):
// a new keyframe predicted with the IMU, its chosen points, the wheel and GNSS factors of the
// interval before it, and the oldest keyframe dropped after its marginalization.
#include <algorithm>
#include <cmath>
#include <utility>

#include "autocal/common/time.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "estimation/point_selection.h"
#include "estimation/sliding_window_internal.h"

namespace autocal {
namespace estimation {

using internal::AttachedFactor;
using internal::StateBlocks;

void SlidingWindowEstimator::Impl::AddKeyframe(int64_t t_ns,
                                               std::optional<lidar::LidarSweep> sweep) {
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

void SlidingWindowEstimator::Impl::SetSweepPoints(lidar::LidarSweep sweep,
                                                  WindowKeyframe* kf) const {
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
  kf->sweep_duration_s = sweep.cloud.has_time() ? sweep.cloud.time_s.maxCoeff() : 0.0;
  kf->sweep = std::move(sweep);
}

void SlidingWindowEstimator::Impl::AttachIntervalMeasurements(WindowKeyframe* from,
                                                              int64_t t_end_ns) {
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
  const std::vector<int> used = internal::Thin(all, options_.wheel_rows.max_samples_per_interval);
  // The non-holonomic sigma scaled for the spacing of the samples used.
  const double non_holonomic_sigma_m_s =
      options_.wheel_rows.non_holonomic_sigma_m_s *
      NonHolonomicSigmaScale(
          options_.wheel_rows.non_holonomic_correlation_s,
          used.empty() ? 0.0 : NsToSeconds(t_end_ns - s.t_ns) / static_cast<double>(used.size()));
  wheel_options.non_holonomic = options_.wheel_rows.non_holonomic;
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
    // The mean gyro over the span around the wheel sample (wheel_rows.gyro_mean_span_s).
    const int64_t half_span_ns = SecondsToNs(0.5 * options_.wheel_rows.gyro_mean_span_s);
    const sensors::GyroMean gyro =
        sensors::MeanGyro(imu_, w.t_ns - half_span_ns, w.t_ns + half_span_ns);
    m.gyro_rad_s =
        gyro.samples > 0 ? gyro.rate_rad_s : sensors::InterpolateImu(imu_, w.t_ns).gyro_rad_s;
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

// Keeps the IMU samples from the last one at or before the oldest keyframe on: the IMU
// factors and the sweeps' motion tables integrate from there.
void SlidingWindowEstimator::Impl::TrimImuBuffer() {
  const int64_t oldest_ns = window_.front()->state.t_ns;
  auto first_after =
      std::upper_bound(imu_.begin(), imu_.end(), oldest_ns,
                       [](int64_t t, const sensors::ImuSample& s) { return t < s.t_ns; });
  if (first_after - imu_.begin() > 1) imu_.erase(imu_.begin(), first_after - 1);
}

}  // namespace estimation
}  // namespace autocal
