#include "autocal/estimation/keyframe_sensor_factors.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/factors/imu_factor.h"
#include "autocal/factors/prior_factors.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "autocal/sensors/body_rate.h"
#include "autocal/sensors/imu_preintegration.h"
#include "estimation/keyframe_interpolation.h"
#include "estimation/time_offset_factors.h"
#include "estimation/turning_axis.h"

namespace autocal {
namespace estimation {
namespace internal {

// Spans beyond this many seconds (about 31 years) do not fit an int64 count of nanoseconds
// with room to add them to a stamp.
constexpr double kMaxSpanS = 1e9;

int64_t GapNs(double gap_s, const std::string& name) {
  if (!std::isfinite(gap_s) || !(gap_s > 0.0) || gap_s > kMaxSpanS) {
    throw Error(name + " must be a positive number of seconds up to 1e9, got " +
                std::to_string(gap_s));
  }
  return SecondsToNs(gap_s);
}

bool InterpolateSortedGnss(const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
                           int64_t t_ns, int64_t max_gap_ns,
                           factors::GnssMeasurement* measurement) {
  const std::optional<Bracket> b = FindBracket(fixes, t_ns, max_gap_ns);
  if (!b) return false;
  const sensors::GnssFix& f0 = fixes[b->first];
  const sensors::GnssFix& f1 = fixes[b->second];
  measurement->p_W_A = (1.0 - b->s) * converter.ToEnu(f0) + b->s * converter.ToEnu(f1);
  // Eq. K2: the interpolated sigma bounds the true one, sqrt((1-s)^2 s0^2 + s^2 s1^2), from
  // above, and stays right when the errors of neighbouring fixes are correlated.
  measurement->sigma_enu_m = (1.0 - b->s) * f0.std_enu_m + b->s * f1.std_enu_m;
  return true;
}

}  // namespace internal

namespace {

using internal::Bracket;
using internal::CheckIncreasing;
using internal::FindBracket;
using internal::GapNs;
using internal::GapNsOrFromStamps;
using internal::InterpolateSortedGnss;

// Ceres would treat a quaternion added implicitly by AddResidualBlock as a Euclidean 4-vector.
void RequireQuaternionBlock(const ceres::Problem& problem, const Eigen::Quaterniond& q,
                            const std::string& name) {
  const double* block = q.coeffs().data();
  if (!problem.HasParameterBlock(block) || dynamic_cast<const geometry::RightQuaternionManifold*>(
                                               problem.GetManifold(block)) == nullptr) {
    throw Error(name +
                " must be added to the problem with geometry::RightQuaternionManifold before its "
                "wheel or GNSS factors");
  }
}

void SetConstantUnless(bool estimate, double* block, ceres::Problem* problem) {
  if (!estimate) problem->SetParameterBlockConstant(block);
}

// sigma <- sqrt(sigma^2 + variance): an independent error added to a row.
void AddVariance(double* row_sigma, double variance) {
  *row_sigma = std::sqrt(*row_sigma * *row_sigma + variance);
}

// The correlated-error scaling (NonHolonomicSigmaScale) at the keyframes' mean spacing.
double KeyframeNonHolonomicSigmaScale(const std::vector<Keyframe>& keyframes, double tau_s) {
  if (keyframes.size() < 2) return 1.0;
  return NonHolonomicSigmaScale(tau_s, NsToSeconds(keyframes.back().t_ns - keyframes.front().t_ns) /
                                           static_cast<double>(keyframes.size() - 1));
}

}  // namespace

double NonHolonomicSigmaScale(double tau_s, double dt_s) {
  if (tau_s == 0.0 || !(dt_s > 0.0)) return 1.0;
  return std::sqrt(std::max(1.0, 2.0 * tau_s / dt_s));
}

double CorneringSlipMS(double compliance_rad_per_m_s2, double speed_m_s, double turn_rate_rad_s) {
  return std::abs(compliance_rad_per_m_s2 * speed_m_s * speed_m_s * turn_rate_rad_s);
}

factors::WheelFactorOptions WithVelocityCovariance(factors::WheelFactorOptions rows,
                                                   const Eigen::Matrix3d& covariance_V) {
  if (covariance_V.isZero(0.0)) return rows;
  AddVariance(&rows.speed_sigma_m_s, covariance_V(0, 0));
  AddVariance(&rows.lateral_sigma_m_s, covariance_V(1, 1));
  AddVariance(&rows.vertical_sigma_m_s, covariance_V(2, 2));
  return rows;
}

factors::WheelFactorOptions WithLeverArmRateCovariance(factors::WheelFactorOptions rows,
                                                       const Eigen::Matrix3d& rate_covariance,
                                                       const Eigen::Quaterniond& q_I_V,
                                                       const Eigen::Vector3d& p_I_V) {
  if (rate_covariance.isZero(0.0)) return rows;
  const Eigen::Matrix3d lever = q_I_V.toRotationMatrix().transpose() * geometry::Hat(p_I_V);
  const Eigen::Matrix3d speed = lever * rate_covariance * lever.transpose();
  return WithVelocityCovariance(rows, speed);
}

double YawRateVariance(const Eigen::Matrix3d& rate_covariance, const Eigen::Quaterniond& q_I_V) {
  const Eigen::Matrix3d r = q_I_V.toRotationMatrix();
  return (r.transpose() * rate_covariance * r)(2, 2);
}

double YawRowRateVariance(const Eigen::Matrix3d& rate_covariance, const Eigen::Quaterniond& q_I_V,
                          const Eigen::Vector3d& yaw_axis_I) {
  if (yaw_axis_I.isZero(0.0)) return YawRateVariance(rate_covariance, q_I_V);
  return yaw_axis_I.dot(rate_covariance * yaw_axis_I);
}

Eigen::Vector3d YawRowAxis(const Eigen::Quaterniond& q_I_V, const Eigen::Vector3d& yaw_axis_I) {
  return yaw_axis_I.isZero(0.0) ? Eigen::Vector3d(q_I_V * Eigen::Vector3d::UnitZ()) : yaw_axis_I;
}

int AddImuFactors(ceres::Problem* problem, const sensors::ImuSamples& imu,
                  std::vector<Keyframe>* keyframes, const KeyframeImuOptions& options) {
  std::vector<Keyframe>& kfs = *keyframes;
  for (size_t k = 0; k < kfs.size(); ++k) {
    RequireQuaternionBlock(*problem, kfs[k].q_W_I, "keyframe q_W_I");
    if (k > 0 && kfs[k].t_ns <= kfs[k - 1].t_ns) {
      throw Error("AddImuFactors: keyframe times must increase (keyframe " + std::to_string(k) +
                  ")");
    }
  }
  if (kfs.size() < 2) return 0;
  if (imu.empty() || imu.front().t_ns > kfs.front().t_ns || imu.back().t_ns < kfs.back().t_ns) {
    throw Error("AddImuFactors: the IMU samples do not cover the keyframes");
  }
  const auto num_intervals = static_cast<int64_t>(kfs.size() - 1);
  std::vector<std::unique_ptr<sensors::ImuPreintegration>> preintegrations(kfs.size() - 1);
  sensors::PreintegrationOptions preintegration;
  preintegration.gravity_m_s2 = options.gravity_m_s2;
  ParallelFor(0, num_intervals, options.num_threads, [&](int64_t begin, int64_t end, int) {
    for (int64_t k = begin; k < end; ++k) {
      const Keyframe& a = kfs[static_cast<size_t>(k)];
      auto pim =
          std::make_unique<sensors::ImuPreintegration>(options.noise, preintegration, a.b_g, a.b_a);
      pim->Integrate(imu, a.t_ns, kfs[static_cast<size_t>(k + 1)].t_ns);
      preintegrations[static_cast<size_t>(k)] = std::move(pim);
    }
  });
  for (size_t k = 0; k + 1 < kfs.size(); ++k) {
    Keyframe& a = kfs[k];
    Keyframe& b = kfs[k + 1];
    problem->AddResidualBlock(factors::ImuFactor::Create(*preintegrations[k]), nullptr,
                              a.q_W_I.coeffs().data(), a.p_W_I.data(), a.v_W_I.data(), a.b_g.data(),
                              a.b_a.data(), b.q_W_I.coeffs().data(), b.p_W_I.data(), b.v_W_I.data(),
                              b.b_g.data(), b.b_a.data());
  }
  return static_cast<int>(num_intervals);
}

void AddBiasPriors(ceres::Problem* problem, Keyframe* keyframe, double gyro_bias_sigma_rad_s,
                   double accel_bias_sigma_m_s2) {
  problem->AddResidualBlock(
      new factors::VectorPriorFactor(
          Eigen::Vector3d::Zero(),
          factors::SqrtInformationFromSigmas(Eigen::Vector3d::Constant(gyro_bias_sigma_rad_s))),
      nullptr, keyframe->b_g.data());
  problem->AddResidualBlock(
      new factors::VectorPriorFactor(
          Eigen::Vector3d::Zero(),
          factors::SqrtInformationFromSigmas(Eigen::Vector3d::Constant(accel_bias_sigma_m_s2))),
      nullptr, keyframe->b_a.data());
}

namespace {

// A keyframe's wheel factor: its cost and the calibration blocks after q_I_V and p_I_V.
struct WheelCost {
  ceres::CostFunction* cost;
  std::vector<double*> intrinsics;
};

// A wheel form's blocks: `intrinsics` in factor order after q_I_V and p_I_V; `scales` are set
// constant unless options.estimate_radii, `tracks` unless options.estimate_track_width.
struct WheelFormBlocks {
  internal::ShiftedWheelForm form;
  std::vector<double*> intrinsics;
  std::vector<double*> scales;
  std::vector<double*> tracks;
};

// The gyro reading the wheel rows start from at t_ns (Eq. K13): the mean gyro over
// gyro_mean_span_s around it (the sample interpolated at t_ns when the span holds none), and
// the variance of that mean's noise per axis.
sensors::GyroReading GyroAt(const sensors::ImuSamples& imu, int64_t t_ns, const Bracket& g,
                            const KeyframeWheelOptions& options) {
  const int64_t half_ns = SecondsToNs(0.5 * options.gyro_mean_span_s);
  const sensors::GyroMean mean =
      half_ns > 0 ? sensors::MeanGyro(imu, t_ns - half_ns, t_ns + half_ns) : sensors::GyroMean();
  sensors::GyroReading out;
  out.rate_rad_s =
      mean.samples > 0
          ? mean.rate_rad_s
          : Eigen::Vector3d((1.0 - g.s) * imu[g.first].gyro_rad_s + g.s * imu[g.second].gyro_rad_s);
  const double sigma = options.gyro_sample_sigma_rad_s;
  out.noise_variance = sigma * sigma / std::max(1, mean.samples);
  return out;
}

// The body rates the rows take at the instants t_ns (Eq. K14): every reading conditioned on
// the spread of all of them; readings without noise are taken as they are.
std::vector<std::optional<sensors::BodyRate>> BodyRatesAt(const sensors::ImuSamples& imu,
                                                          const std::vector<int64_t>& t_ns,
                                                          int64_t max_imu_gap_ns,
                                                          const KeyframeWheelOptions& options) {
  std::vector<std::optional<sensors::GyroReading>> readings(t_ns.size());
  std::vector<sensors::GyroReading> present;
  for (size_t k = 0; k < t_ns.size(); ++k) {
    const std::optional<Bracket> g = FindBracket(imu, t_ns[k], max_imu_gap_ns);
    if (!g) continue;
    readings[k] = GyroAt(imu, t_ns[k], *g, options);
    present.push_back(*readings[k]);
  }
  std::vector<std::optional<sensors::BodyRate>> rates(t_ns.size());
  const bool condition = options.gyro_sample_sigma_rad_s > 0.0 && present.size() >= 2;
  const sensors::BodyRatePrior prior =
      condition ? sensors::BodyRatePrior::Fit(present) : sensors::BodyRatePrior();
  for (size_t k = 0; k < t_ns.size(); ++k) {
    if (!readings[k]) continue;
    rates[k] = condition ? prior.Condition(*readings[k])
                         : sensors::BodyRate{readings[k]->rate_rad_s, Eigen::Matrix3d::Zero()};
  }
  return rates;
}

// The axis, in I, the vehicle turns about (Eq. K13c), from the rows' body-rate readings.
std::optional<Eigen::Vector3d> TurningAxis(
    const std::vector<std::optional<sensors::BodyRate>>& rates, const Eigen::Vector3d& up_I,
    double max_error_rad) {
  internal::TurningRateSpread spread;
  for (const auto& rate : rates) {
    if (rate) spread.Add(rate->rate_rad_s);
  }
  return spread.Axis(up_I, max_error_rad);
}

// A keyframe's wheel values (the form's two) for its rows: the forward-speed row's at the
// instant, the yaw-rate row's averaged over the span the gyro reading averages (Eq. K13b; the
// instant's where the samples do not cover it), each with the weights that give its noise.
struct WheelValues {
  internal::WeightedMean<Eigen::Vector2d> speed_row;
  internal::WeightedMean<Eigen::Vector2d> yaw_row;

  // One sample's values for both rows.
  static WheelValues Of(const Eigen::Vector2d& sample) { return {{sample, 1.0}, {sample, 1.0}}; }

  // The rows' sigmas for these values. A weighted mean of independent samples has the noise
  // of one sample times sqrt(weight_squares): the yaw-rate row's over its span, scaled by
  // yaw_span_scale, sqrt(max(1, span / keyframe spacing)), because the spans overlap when
  // keyframes lie closer than a span and a sample shared by k rows would count k times
  // (Eq. K13b). The forward-speed row keeps one sample's sigma at the interpolated instant
  // (docs/keyframe_factors.md, K13b: its own, about 0.8 of it, is measured and open).
  factors::WheelFactorOptions Whitened(factors::WheelFactorOptions rows,
                                       double yaw_span_scale) const {
    rows.yaw_rate_sigma_rad_s *= std::sqrt(yaw_row.weight_squares) * yaw_span_scale;
    return rows;
  }
};

// With the wheel clock at the IMU's: the values interpolated at the keyframe (Eq. K1), the
// yaw-rate row's over [t_k - half_span, t_k + half_span] where the samples cover that span.
template <typename Samples, typename ToValue>
std::optional<WheelValues> InstantValues(const Samples& wheel, int64_t t_k_ns, int64_t half_span_ns,
                                         int64_t max_gap_ns, ToValue to_value) {
  const auto instant = internal::MeanOverSpan(wheel, t_k_ns, t_k_ns, max_gap_ns, to_value);
  if (!instant) return std::nullopt;
  return WheelValues{*instant, internal::MeanOverSpan(wheel, t_k_ns - half_span_ns,
                                                      t_k_ns + half_span_ns, max_gap_ns, to_value)
                                   .value_or(*instant)};
}

// AddWheelFactors for the samples of any wheel form, whose two values to_value(sample) gives.
// With the wheel clock at the IMU's (offset 0, not estimated) make_cost(speed_row, yaw_row,
// gyro, factor_options) builds a keyframe's factor from the values interpolated at it (Eq. K1),
// those averaged over the gyro's span (Eq. K13b) and the rows' body rate. Otherwise each
// keyframe takes the values of its nearest sample on the wheel clock (Eq. K17) against its
// state carried to the sample's IMU time (Eq. K16, internal::ShiftedWheelResidual) on the
// offset block, held constant unless options.estimate_time_offset.
template <typename Samples, typename MakeCost, typename ToValue>
int AddWheelFactorsOf(ceres::Problem* problem, const sensors::ImuSamples& imu, const Samples& wheel,
                      std::vector<Keyframe>* keyframes, sensors::Calibration* calibration,
                      const KeyframeWheelOptions& options, const WheelFormBlocks& form_blocks,
                      MakeCost make_cost, ToValue to_value) {
  CheckIncreasing(wheel, "AddWheelFactors: wheel");
  CheckIncreasing(imu, "AddWheelFactors: IMU");
  const int64_t max_wheel_gap_ns =
      GapNsOrFromStamps(options.max_wheel_gap_s, wheel, "max_wheel_gap_s");
  const int64_t max_imu_gap_ns = GapNsOrFromStamps(options.max_imu_gap_s, imu, "max_imu_gap_s");
  RequireQuaternionBlock(*problem, calibration->q_I_V, "q_I_V");
  for (const Keyframe& kf : *keyframes) {
    RequireQuaternionBlock(*problem, kf.q_W_I, "keyframe q_W_I");
  }

  sensors::Calibration& c = *calibration;
  double* offset = &c.time_offset_wheel_imu_s;
  if (!std::isfinite(*offset)) {
    throw Error("AddWheelFactors: time_offset_wheel_imu_s must be finite");
  }
  const bool shifted = options.estimate_time_offset || *offset != 0.0;
  // The sample each keyframe takes on the wheel clock (Eq. K17), at the offset's value now.
  const std::vector<std::optional<size_t>> paired =
      shifted ? internal::PairedSamples(wheel, *keyframes, *offset, max_wheel_gap_ns)
              : std::vector<std::optional<size_t>>();
  // One loss for all the factors (the problem deletes a shared loss once); it is ours to
  // delete until a residual block uses it.
  std::unique_ptr<ceres::LossFunction> unused_loss(factors::MakeLossFunction(options.loss));
  ceres::LossFunction* loss = unused_loss.get();
  // Each non-holonomic row's sigma scaled for its own correlation time.
  factors::WheelFactorOptions factor_options = options.factor;
  for (const auto& [name, tau_s, sigma_m_s] :
       {std::tuple{"lateral", options.lateral_correlation_s, &factor_options.lateral_sigma_m_s},
        std::tuple{"vertical", options.vertical_correlation_s,
                   &factor_options.vertical_sigma_m_s}}) {
    if (!(tau_s >= 0.0) || !std::isfinite(tau_s)) {
      throw Error(std::string("AddWheelFactors: ") + name +
                  "_correlation_s must be finite and >= 0, got " + std::to_string(tau_s));
    }
    *sigma_m_s *= KeyframeNonHolonomicSigmaScale(*keyframes, tau_s);
  }
  const double compliance = options.cornering_compliance_rad_per_m_s2;
  if (!(compliance >= 0.0) || !std::isfinite(compliance)) {
    throw Error("AddWheelFactors: cornering_compliance_rad_per_m_s2 must be finite and >= 0, got " +
                std::to_string(compliance));
  }
  // The turn's slip is added in quadrature below, which would hide a sign.
  if (!(options.factor.lateral_sigma_m_s > 0.0) ||
      !std::isfinite(options.factor.lateral_sigma_m_s)) {
    throw Error("AddWheelFactors: factor.lateral_sigma_m_s must be finite and > 0, got " +
                std::to_string(options.factor.lateral_sigma_m_s));
  }
  const double lateral_scale =
      KeyframeNonHolonomicSigmaScale(*keyframes, options.lateral_correlation_s);
  // The yaw-rate rows' sigma follows the track (Eq. F22b), stated at the track's start, where
  // the wheels' rates carry the encoders' white noise. Not for the controller's twist: its yaw
  // rate errs by the platform's slip, which b_eff models, not by noise in its rate.
  if (factor_options.yaw_row_track_m == 0.0 && !form_blocks.tracks.empty() &&
      form_blocks.form.form != sensors::WheelForm::kSpeedYawRate) {
    factor_options.yaw_row_track_m = *form_blocks.tracks.front();
  }
  if (!(options.gyro_mean_span_s >= 0.0) || !(options.gyro_mean_span_s <= internal::kMaxSpanS) ||
      !(options.gyro_sample_sigma_rad_s >= 0.0) ||
      !std::isfinite(options.gyro_sample_sigma_rad_s)) {
    throw Error(
        "AddWheelFactors: gyro_mean_span_s must be within [0, 1e9] s and gyro_sample_sigma_rad_s "
        "finite and >= 0");
  }
  // The wheels' mean over the gyro reading's span for the yaw-rate rows (Eq. K13b); a moving
  // mean over a span T is an error correlated over T / 2 in the sense of Eq. K6. With the
  // clocks offset, both rows keep the paired sample: the offset's rows take the gyro's slope at
  // the sample as the rate's change (ShiftedWheelResidual), a regressor whose noise a quieter,
  // averaged row would count as information.
  const int64_t half_span_ns = SecondsToNs(0.5 * options.gyro_mean_span_s);
  const double yaw_span_scale =
      shifted ? 1.0 : KeyframeNonHolonomicSigmaScale(*keyframes, 0.5 * options.gyro_mean_span_s);
  // The rows' body rate at each keyframe, or where its sample was taken (Eq. K17).
  std::vector<int64_t> rate_ns;
  for (size_t k = 0; k < keyframes->size(); ++k) {
    rate_ns.push_back(shifted && paired[k] ? wheel[*paired[k]].t_ns + SecondsToNs(*offset)
                                           : (*keyframes)[k].t_ns);
  }
  const std::vector<std::optional<sensors::BodyRate>> rates =
      BodyRatesAt(imu, rate_ns, max_imu_gap_ns, options);
  if (const std::optional<Eigen::Vector3d> axis =
          shifted ? std::nullopt
                  : TurningAxis(rates, c.q_I_V * Eigen::Vector3d::UnitZ(),
                                options.max_turning_axis_error_deg * kDegToRad)) {
    factor_options.yaw_axis_I = *axis;
  }
  const Eigen::Vector3d turning_axis_I = YawRowAxis(c.q_I_V, factor_options.yaw_axis_I);
  int added = 0;
  for (size_t k = 0; k < keyframes->size(); ++k) {
    if (!rates[k]) continue;
    Keyframe& kf = (*keyframes)[k];
    if (shifted && !paired[k]) continue;
    const std::optional<WheelValues> values =
        shifted ? WheelValues::Of(to_value(wheel[*paired[k]]))
                : InstantValues(wheel, kf.t_ns, half_span_ns, max_wheel_gap_ns, to_value);
    if (!values) continue;
    const sensors::BodyRate& gyro = *rates[k];
    factors::WheelFactorOptions turning = values->Whitened(factor_options, yaw_span_scale);
    // The slip out of the keyframe's turn (Eq. K6c), correlated as the row's straight part.
    turning.lateral_sigma_m_s =
        lateral_scale * std::hypot(options.factor.lateral_sigma_m_s,
                                   CorneringSlipMS(compliance, kf.v_W_I.norm(),
                                                   gyro.rate_rad_s.dot(turning_axis_I)));
    factors::WheelFactorOptions rows =
        WithLeverArmRateCovariance(turning, gyro.covariance, c.q_I_V, c.p_I_V);
    if (!gyro.covariance.isZero(0.0)) {
      const double variance =
          YawRowRateVariance(gyro.covariance, c.q_I_V, factor_options.yaw_axis_I);
      AddVariance(&rows.yaw_rate_sigma_rad_s, variance);
      AddVariance(&rows.yaw_rate_gyro_sigma_rad_s, variance);  // its gyro part (Eq. F22b)
    }
    WheelCost factor{nullptr, {}};
    if (!shifted) {
      factor = make_cost(values->speed_row.value, values->yaw_row.value, gyro.rate_rad_s, rows);
    } else {
      const std::optional<internal::ImuAroundKeyframe> around =
          internal::ImuAround(imu, kf.t_ns, options.gravity_m_s2, max_imu_gap_ns);
      if (!around) continue;
      const internal::PairedWheelSample taken{values->speed_row.value, wheel[*paired[k]].t_ns,
                                              *offset, gyro.rate_rad_s};
      factor.cost =
          internal::ShiftedWheelResidual::Create(taken, kf.t_ns, *around, form_blocks.form, rows);
    }
    std::vector<double*> blocks = {kf.q_W_I.coeffs().data(), kf.v_W_I.data(), kf.b_g.data()};
    if (shifted) blocks.push_back(kf.b_a.data());
    blocks.insert(blocks.end(), {c.q_I_V.coeffs().data(), c.p_I_V.data()});
    blocks.insert(blocks.end(), form_blocks.intrinsics.begin(), form_blocks.intrinsics.end());
    if (shifted) blocks.push_back(offset);
    problem->AddResidualBlock(factor.cost, loss, blocks);
    unused_loss.release();
    ++added;
  }
  if (added == 0) return 0;
  SetConstantUnless(options.estimate_vehicle_rotation, c.q_I_V.coeffs().data(), problem);
  SetConstantUnless(options.estimate_vehicle_translation, c.p_I_V.data(), problem);
  for (double* block : form_blocks.scales)
    SetConstantUnless(options.estimate_radii, block, problem);
  for (double* block : form_blocks.tracks) {
    SetConstantUnless(options.estimate_track_width, block, problem);
  }
  if (shifted) SetConstantUnless(options.estimate_time_offset, offset, problem);
  return added;
}

}  // namespace

int AddWheelFactors(ceres::Problem* problem, const sensors::ImuSamples& imu,
                    const sensors::WheelSamples& wheel, std::vector<Keyframe>* keyframes,
                    sensors::Calibration* calibration, const KeyframeWheelOptions& options) {
  sensors::Calibration& c = *calibration;
  WheelFormBlocks blocks;
  blocks.form.form = sensors::WheelForm::kAngularRates;
  blocks.form.shared_radius = options.factor.shared_radius;
  blocks.scales = {&c.wheel_radius_left_m};
  if (!blocks.form.shared_radius) blocks.scales.push_back(&c.wheel_radius_right_m);
  blocks.tracks = {&c.track_width_m};
  blocks.intrinsics = blocks.scales;
  blocks.intrinsics.push_back(&c.track_width_m);
  return AddWheelFactorsOf(
      problem, imu, wheel, keyframes, calibration, options, blocks,
      [&](const Eigen::Vector2d& speed_row, const Eigen::Vector2d& yaw_row,
          const Eigen::Vector3d& gyro, const factors::WheelFactorOptions& factor_options) {
        factors::WheelMeasurement m;
        m.left_rad_s = speed_row(0);
        m.right_rad_s = speed_row(1);
        m.gyro_rad_s = gyro;
        m.yaw_row_rad_s = yaw_row;
        return WheelCost{factors::WheelFactor::Create(m, factor_options), blocks.intrinsics};
      },
      [](const sensors::WheelSample& w) { return Eigen::Vector2d(w.left_rad_s, w.right_rad_s); });
}

WheelData WheelData::AngularRates(sensors::WheelSamples samples) {
  WheelData data;
  data.form = sensors::WheelForm::kAngularRates;
  data.rates = std::move(samples);
  return data;
}

bool WheelData::empty() const {
  switch (form) {
    case sensors::WheelForm::kLinearSpeeds:
      return speeds.empty();
    case sensors::WheelForm::kSpeedYawRate:
      return odometry.empty();
    case sensors::WheelForm::kAngularRates:
      break;
  }
  return rates.empty();
}

int AddWheelFactors(ceres::Problem* problem, const sensors::ImuSamples& imu, const WheelData& wheel,
                    std::vector<Keyframe>* keyframes, sensors::Calibration* calibration,
                    const KeyframeWheelOptions& options) {
  sensors::Calibration& c = *calibration;
  WheelFormBlocks blocks;
  blocks.form.form = wheel.form;
  switch (wheel.form) {
    case sensors::WheelForm::kAngularRates:
      return AddWheelFactors(problem, imu, wheel.rates, keyframes, calibration, options);
    case sensors::WheelForm::kLinearSpeeds:
      blocks.scales = {&c.wheel_speed_scale_left, &c.wheel_speed_scale_right};
      blocks.tracks = {&c.track_width_m};
      blocks.intrinsics = {&c.wheel_speed_scale_left, &c.wheel_speed_scale_right, &c.track_width_m};
      return AddWheelFactorsOf(
          problem, imu, wheel.speeds, keyframes, calibration, options, blocks,
          [&](const Eigen::Vector2d& speed_row, const Eigen::Vector2d& yaw_row,
              const Eigen::Vector3d& gyro, const factors::WheelFactorOptions& factor_options) {
            factors::WheelSpeedMeasurement m;
            m.left_m_s = speed_row(0);
            m.right_m_s = speed_row(1);
            m.gyro_rad_s = gyro;
            m.yaw_row_m_s = yaw_row;
            return WheelCost{factors::WheelSpeedResidual::Create(m, factor_options),
                             blocks.intrinsics};
          },
          [](const sensors::WheelSpeedSample& w) {
            return Eigen::Vector2d(w.left_m_s, w.right_m_s);
          });
    case sensors::WheelForm::kSpeedYawRate:
      break;
  }
  if (!(wheel.controller_track_m > 0.0) || !std::isfinite(wheel.controller_track_m)) {
    throw Error("AddWheelFactors: the controller track b_ctrl must be positive");
  }
  blocks.form.controller_track_m = wheel.controller_track_m;
  blocks.scales = {&c.odometry_speed_scale};
  blocks.tracks = {&c.effective_track_m};
  blocks.intrinsics = {&c.odometry_speed_scale, &c.effective_track_m};
  return AddWheelFactorsOf(
      problem, imu, wheel.odometry, keyframes, calibration, options, blocks,
      [&](const Eigen::Vector2d& speed_row, const Eigen::Vector2d& yaw_row,
          const Eigen::Vector3d& gyro, const factors::WheelFactorOptions& factor_options) {
        factors::OdometryMeasurement m;
        m.speed_m_s = speed_row(0);
        m.yaw_rate_rad_s = yaw_row(1);
        m.controller_track_m = wheel.controller_track_m;
        m.gyro_rad_s = gyro;
        return WheelCost{factors::OdometryTwistResidual::Create(m, factor_options),
                         blocks.intrinsics};
      },
      [](const sensors::OdometrySample& w) {
        return Eigen::Vector2d(w.speed_m_s, w.yaw_rate_rad_s);
      });
}

bool InterpolateGnss(const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
                     int64_t t_ns, double max_fix_gap_s, factors::GnssMeasurement* measurement) {
  CheckIncreasing(fixes, "GNSS fix");
  return InterpolateSortedGnss(fixes, converter, t_ns, GapNs(max_fix_gap_s, "max_fix_gap_s"),
                               measurement);
}

namespace {

// Whether a fix enters two keyframes' interpolated rows (Eq. K1) with a weight: keyframes
// denser than the fixes (two between the same two fixes, or one on a fix and one beside it),
// whose rows would count the fix's information again for each keyframe at the full sigma of
// Eq. K2 (ten keyframes a fix: sigmas sqrt(10) times too small), or about as dense but out of
// phase, where the straight line between the fixes misses a curving antenna.
bool KeyframesShareAFix(const sensors::GnssFixes& fixes, const std::vector<Keyframe>& kfs,
                        int64_t max_gap_ns) {
  std::vector<bool> used(fixes.size(), false);
  for (const Keyframe& kf : kfs) {
    const std::optional<internal::Bracket> b = internal::FindBracket(fixes, kf.t_ns, max_gap_ns);
    if (!b) continue;
    if (used[b->first] || (b->second != b->first && used[b->second])) return true;
    used[b->first] = true;
    used[b->second] = true;
  }
  return false;
}

// A GNSS row: the keyframe and the fix it takes, carried to the fix (Eqs. K16, K17); without a
// fix, the fixes interpolated to the keyframe (Eqs. K1, K2).
struct GnssRow {
  size_t keyframe = 0;
  std::optional<size_t> fix;
};

// The rows AddGnssFactors adds (see there): with a clock each keyframe takes its nearest fix
// (NearestSamples, which the clock's re-pairing compares); without one, where keyframes would
// share a fix, each fix serves its nearest keyframe (NearestKeyframes: every fix once, however
// dense); else each keyframe with bracketing fixes takes them interpolated.
std::vector<GnssRow> GnssRows(const sensors::GnssFixes& fixes, const std::vector<Keyframe>& kfs,
                              double offset_s, bool clock, int64_t max_gap_ns) {
  std::vector<GnssRow> rows;
  if (clock) {
    const std::vector<std::optional<size_t>> paired =
        internal::PairedSamples(fixes, kfs, offset_s, max_gap_ns);
    for (size_t k = 0; k < kfs.size(); ++k) {
      if (paired[k]) rows.push_back({k, paired[k]});
    }
  } else if (KeyframesShareAFix(fixes, kfs, max_gap_ns)) {
    const std::vector<std::optional<size_t>> serves =
        internal::NearestKeyframes(fixes, kfs, max_gap_ns / 2);
    for (size_t j = 0; j < fixes.size(); ++j) {
      if (serves[j]) rows.push_back({*serves[j], j});
    }
  } else {
    for (size_t k = 0; k < kfs.size(); ++k) {
      if (FindBracket(fixes, kfs[k].t_ns, max_gap_ns)) rows.push_back({k, std::nullopt});
    }
  }
  return rows;
}

}  // namespace

int AddGnssFactors(ceres::Problem* problem, const sensors::ImuSamples& imu,
                   const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
                   std::vector<Keyframe>* keyframes, sensors::Calibration* calibration,
                   const KeyframeGnssOptions& options) {
  CheckIncreasing(fixes, "AddGnssFactors: GNSS fix");
  const int64_t max_gap_ns = GapNsOrFromStamps(options.max_fix_gap_s, fixes, "max_fix_gap_s");
  for (const Keyframe& kf : *keyframes) {
    RequireQuaternionBlock(*problem, kf.q_W_I, "keyframe q_W_I");
  }
  double* offset = &calibration->time_offset_gnss_imu_s;
  if (!std::isfinite(*offset)) throw Error("AddGnssFactors: time_offset_gnss_imu_s must be finite");
  options.noise_scale.Check("AddGnssFactors");
  const std::vector<GnssRow> rows = GnssRows(
      fixes, *keyframes, *offset, options.estimate_time_offset || *offset != 0.0, max_gap_ns);
  const bool shifted = !rows.empty() && rows.front().fix.has_value();
  if (shifted) CheckIncreasing(imu, "AddGnssFactors: IMU");
  // The IMU carries states only on the shifted rows; a set gap is checked either way.
  const sensors::ImuSamples no_imu;
  const int64_t max_imu_gap_ns =
      GapNsOrFromStamps(options.max_imu_gap_s, shifted ? imu : no_imu, "max_imu_gap_s");

  // One loss for all the factors (the problem deletes a shared loss once); it is ours to
  // delete until a residual block uses it.
  std::unique_ptr<ceres::LossFunction> unused_loss(factors::MakeLossFunction(options.loss));
  ceres::LossFunction* loss = unused_loss.get();
  std::vector<bool> with_fix(keyframes->size(), false);
  for (const GnssRow& row : rows) {
    Keyframe& kf = (*keyframes)[row.keyframe];
    factors::GnssMeasurement m;
    std::optional<internal::ImuAroundKeyframe> around;  // carries the state to the fix
    if (!row.fix) {
      InterpolateSortedGnss(fixes, converter, kf.t_ns, max_gap_ns, &m);
    } else {
      around = internal::ImuAround(imu, kf.t_ns, options.gravity_m_s2, max_imu_gap_ns);
      if (!around) continue;
      m = factors::GnssMeasurement::FromFix(fixes[*row.fix], converter);
    }
    m.sigma_enu_m = options.noise_scale.Applied(m.sigma_enu_m);
    for (const factors::GnssAxes axes :
         {factors::GnssAxes::kHorizontal, factors::GnssAxes::kVertical}) {
      if (!row.fix) {
        problem->AddResidualBlock(factors::GnssFactor::Create(m, axes), loss,
                                  kf.q_W_I.coeffs().data(), kf.p_W_I.data(),
                                  calibration->p_I_A.data());
      } else {
        problem->AddResidualBlock(
            internal::ShiftedGnssResidual::Create(m, fixes[*row.fix].t_ns, kf.t_ns, *around, axes),
            loss, kf.q_W_I.coeffs().data(), kf.p_W_I.data(), kf.v_W_I.data(), kf.b_g.data(),
            kf.b_a.data(), calibration->p_I_A.data(), offset);
      }
    }
    unused_loss.release();
    with_fix[row.keyframe] = true;
  }
  const int added = static_cast<int>(std::count(with_fix.begin(), with_fix.end(), true));
  if (added == 0) return 0;
  SetConstantUnless(options.estimate_lever_arm, calibration->p_I_A.data(), problem);
  if (shifted) SetConstantUnless(options.estimate_time_offset, offset, problem);
  return added;
}

GnssNoiseFromResiduals MeasureGnssNoise(const sensors::ImuSamples& imu,
                                        const sensors::GnssFixes& fixes,
                                        const sensors::EnuConverter& converter,
                                        std::vector<Keyframe>* keyframes,
                                        sensors::Calibration* calibration,
                                        const KeyframeGnssOptions& options) {
  // The GNSS rows alone, on their own problem: the values are only read.
  geometry::RightQuaternionManifold quaternion_manifold;
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem rows(problem_options);
  for (Keyframe& kf : *keyframes) {
    rows.AddParameterBlock(kf.q_W_I.coeffs().data(), 4, &quaternion_manifold);
  }
  KeyframeGnssOptions stated = options;
  stated.noise_scale = {};
  AddGnssFactors(&rows, imu, fixes, converter, keyframes, calibration, stated);
  std::vector<ceres::ResidualBlockId> blocks;
  rows.GetResidualBlocks(&blocks);
  GnssRowScatter scatter;
  double whitened[3];
  for (const ceres::ResidualBlockId id : blocks) {
    const int n = rows.GetCostFunctionForResidualBlock(id)->num_residuals();
    bool finite = rows.EvaluateResidualBlock(id, false, nullptr, whitened, nullptr);
    for (int k = 0; finite && k < n; ++k) {
      // The horizontal blocks hold two rows, the vertical ones one (factors::GnssAxes).
      finite = n == 2 ? scatter.AddHorizontal(whitened[k]) : scatter.AddVertical(whitened[k]);
    }
    if (!finite) {
      throw Error(
          "MeasureGnssNoise: the GNSS rows could not be evaluated at the solved trajectory (a "
          "non-finite residual): the fixes' scatter (Eq. N2) cannot be measured");
    }
  }
  return scatter.Noise();
}

}  // namespace estimation
}  // namespace autocal
