#pragma once

// IMU, wheel and GNSS factors on the keyframes of a batch problem, one per LiDAR sweep
// (docs/keyframe_factors.md). Wheel and GNSS samples are interpolated linearly to a keyframe's
// time t_k between the two samples bracketing it (Eq. K1), the wheels' yaw-rate row averaged
// over the gyro reading's span instead (Eq. K13b); a keyframe whose samples lie farther apart
// than a maximum gap (a dropout, an outage) gets no factor. With GNSS factors W
// is the converter's ENU frame and the fixes hold the gauge; AlignKeyframesToGnss first moves
// an initializer's gravity-aligned trajectory there. Quaternion blocks (each keyframe's q_W_I, the
// calibration's q_I_V) must already be in the problem with geometry::RightQuaternionManifold;
// the functions add every other block they use.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "autocal/estimation/gnss_noise.h"
#include "autocal/estimation/keyframe.h"
#include "autocal/factors/gnss_factor.h"
#include "autocal/factors/loss.h"
#include "autocal/factors/wheel_factor.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/gnss_enu.h"
#include "autocal/sensors/measurements.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace estimation {

struct KeyframeImuOptions {
  sensors::ImuNoise noise;
  double gravity_m_s2 = 9.80665;
  int num_threads = 1;  // preintegration runs in parallel
};

// Adds one ImuFactor (Eq. F10) per pair of consecutive keyframes, preintegrated at the first
// one's biases; returns the number added (ownership as AddWheelFactors). Throws autocal::Error
// when the samples do not cover the keyframes, their times do not increase, or a keyframe
// q_W_I is missing from the problem or has no manifold.
int AddImuFactors(ceres::Problem* problem, const sensors::ImuSamples& imu,
                  std::vector<Keyframe>* keyframes, const KeyframeImuOptions& options);

// Adds a prior at zero on the keyframe's biases (Eq. F41, 1-sigma per axis), as a problem
// without other bias information needs on its first keyframe. Ownership as AddWheelFactors.
void AddBiasPriors(ceres::Problem* problem, Keyframe* keyframe, double gyro_bias_sigma_rad_s,
                   double accel_bias_sigma_m_s2);

// sqrt(max(1, 2 tau_s / dt_s)), the correlated-error scaling of the non-holonomic rows' sigma
// (docs/keyframe_factors.md): an error correlated over tau_s seen every dt_s carries about
// T / (2 tau_s) samples' information, not T / dt_s. 1 for tau_s = 0 or dt_s <= 0.
double NonHolonomicSigmaScale(double tau_s, double dt_s);

// The rear axle's sideways slip out of a turn (docs/keyframe_factors.md, Eq. K6c): c v^2 |omega|
// at speed v and turning rate omega, for a cornering compliance c (rad of slip angle per m/s^2
// of lateral acceleration v omega). The lateral row's sigma adds it in quadrature to the
// straight-driving slip.
double CorneringSlipMS(double compliance_rad_per_m_s2, double speed_m_s, double turn_rate_rad_s);

// The wheel rows with an independent error of the rear axle's velocity in V (covariance C_V:
// forward, lateral, vertical) added: the speed, lateral and vertical rows' variances grow by the
// diagonal of C_V.
factors::WheelFactorOptions WithVelocityCovariance(factors::WheelFactorOptions rows,
                                                   const Eigen::Matrix3d& covariance_V);

// Eq. K13: the body rate's remaining error (covariance P in I, Eq. K14) in the wheel rows. The
// speed rows see it through the lever arm w x p_I_V, as the velocity covariance
// R^T [p]x P [p]x^T R in V (R = R_I_V, p = p_I_V; WithVelocityCovariance); the yaw-rate row
// sees (R^T P R)_zz.
factors::WheelFactorOptions WithLeverArmRateCovariance(factors::WheelFactorOptions rows,
                                                       const Eigen::Matrix3d& rate_covariance,
                                                       const Eigen::Quaterniond& q_I_V,
                                                       const Eigen::Vector3d& p_I_V);
double YawRateVariance(const Eigen::Matrix3d& rate_covariance, const Eigen::Quaterniond& q_I_V);
// The yaw-rate row's share of the rate's covariance P: about yaw_axis_I, u^T P u, when the row
// reads the rate about that axis (Eq. K13c, WheelFactorOptions::yaw_axis_I), else
// YawRateVariance.
double YawRowRateVariance(const Eigen::Matrix3d& rate_covariance, const Eigen::Quaterniond& q_I_V,
                          const Eigen::Vector3d& yaw_axis_I);
// The axis, in I, the yaw-rate row reads the body rate about: yaw_axis_I, or V's up axis
// through q_I_V when it is zero.
Eigen::Vector3d YawRowAxis(const Eigen::Quaterniond& q_I_V, const Eigen::Vector3d& yaw_axis_I);

struct KeyframeWheelOptions {
  // Sigmas and rows of each factor. With factor.shared_radius the left radius block
  // (Calibration::wheel_radius_left_m) stands for both wheels; the right one is not touched.
  factors::WheelFactorOptions factor;
  factors::LossOptions loss = factors::FactorLossOptions().wheel;  // Huber, 2 sigma
  // Largest spacing of the wheel samples bracketing t_k (one lost sample is bridged, a dropout
  // is not); 0: Eq. T1 from the wheel samples' own stamps (sensors/sample_timing.h: 0.025 s for
  // a 100 Hz encoder, 0.25 s for 10 Hz odometry), as the offline calibration derives it.
  double max_wheel_gap_s = 0.0;
  double max_imu_gap_s = 0.0;  // the same for the raw gyro at t_k (0: Eq. T1 from the IMU's)
  // The rows take the mean gyro over this span around t_k (Eq. K13), which keeps the gyro's
  // white noise out of the lever-arm term w x p_I_V; 0 takes the interpolated sample. The
  // yaw-rate row compares it with the wheels' mean over the same span (Eq. K13b).
  double gyro_mean_span_s = 0.0;
  // 1-sigma of one gyro sample (density * sqrt(rate)). With it the rows take the rate given the
  // mean (conditioned on the spread of all keyframes' means, Eq. K14) and its remaining error
  // enters their sigma (Eq. K13). 0: the mean as exact.
  double gyro_sample_sigma_rad_s = 0.0;
  // The yaw-rate rows read the body rate about the axis the vehicle turns about, measured from
  // the keyframes' readings (Eq. K13c), when that axis's standard error is below this; else
  // about V's up axis through q_I_V, whose tilt error e lengthens the track by b e^2 / 2. At
  // 1 deg the axis's own error lengthens a 1.6 m track by at most 0.25 mm. 0: V's up axis.
  double max_turning_axis_error_deg = 1.0;
  // Correlation times of the non-holonomic rows' model errors: each row's sigma is scaled by
  // NonHolonomicSigmaScale at the mean keyframe spacing; 0: a white row (docs/keyframe_factors.md,
  // "Correlated model error of the non-holonomic rows"). The vertical speed follows the body's
  // pitch on its suspension, so speeding up and slowing down cancel: twice its autocorrelation's
  // integral over +-10 s on the simulated urban drive (0.25 s). The lateral speed is the rear
  // axle's slip, which keeps a turn's sign for the whole turn and need not average out over a
  // drive (more left turns than right): the vertical speed's integral to its first zero.
  double lateral_correlation_s = 2.0;
  double vertical_correlation_s = 0.5;
  // The rear axle's cornering compliance c (sensors::WheelConfig): each keyframe's lateral row
  // adds the slip c v^2 |omega| of its speed and turning rate, in quadrature, to
  // factor.lateral_sigma_m_s, the slip driving straight, before the correlated-error scaling
  // (Eq. K6c). 0: one sigma.
  double cornering_compliance_rad_per_m_s2 = 0.0;
  // Blocks not estimated are set constant (estimated ones are not made variable: a caller may
  // have fixed them).
  bool estimate_vehicle_rotation = true;     // q_I_V
  bool estimate_vehicle_translation = true;  // p_I_V
  bool estimate_radii = true;
  bool estimate_track_width = true;
  bool estimate_time_offset = false;  // time_offset_wheel_imu_s (Eq. K16); else held
  // Gravity's magnitude, which carries a keyframe's velocity to a sample's instant (Eq. K16).
  double gravity_m_s2 = 9.80665;
};

// Adds one WheelFactor (Eq. F22) per keyframe that the wheel and IMU samples bracket within
// the maximum gaps, on the keyframe's q_W_I, v_W_I, b_g and the calibration's q_I_V, p_I_V,
// radii and track width. With a wheel clock offset (time_offset_wheel_imu_s nonzero, or
// options.estimate_time_offset) each keyframe takes its nearest sample on the wheel clock,
// within max_wheel_gap_s / 2 of it (Eq. K17), against its state carried to the sample's IMU
// time (Eq. K16): the keyframe's b_a and the offset block enter the factor too. The keyframes and
// the calibration must outlive the problem (their members are the blocks); the problem owns the
// cost and loss functions. Returns the number of factors added. Throws autocal::Error for stamps
// that do not increase, negative gaps, or a quaternion block missing from the problem or
// without a manifold.
int AddWheelFactors(ceres::Problem* problem, const sensors::ImuSamples& imu,
                    const sensors::WheelSamples& wheel, std::vector<Keyframe>* keyframes,
                    sensors::Calibration* calibration, const KeyframeWheelOptions& options = {});

// Wheel data in the form a dataset carries them (io::Dataset, datasets/README.md "Wheel
// forms"): only the form's samples are read.
struct WheelData {
  sensors::WheelForm form = sensors::WheelForm::kAngularRates;
  sensors::WheelSamples rates;        // angular_rates
  sensors::WheelSpeedSamples speeds;  // linear_speeds: the rear pair is used
  sensors::OdometrySamples odometry;  // speed_yaw_rate
  double controller_track_m = 1.0;    // speed_yaw_rate: b_ctrl (> 0)

  // The samples of the form, as angular rates when given so.
  static WheelData AngularRates(sensors::WheelSamples samples);
  // Whether the form holds no sample.
  bool empty() const;
};

// The same for any form: WheelFactor for angular rates, WheelSpeedResidual (Eq. F25) for
// linear speeds, OdometryTwistResidual (Eq. F26) for speed and yaw rate. options.factor carries
// the form's sigmas (WheelFactorOptions::FromEncoderNoise, FromWheelSpeedNoise,
// FromOdometryNoise); estimate_radii holds or frees the form's scales (radii, speed scales,
// k_v), estimate_track_width its track (b or b_eff). Throws as above, and for a non-positive
// controller track.
int AddWheelFactors(ceres::Problem* problem, const sensors::ImuSamples& imu, const WheelData& wheel,
                    std::vector<Keyframe>* keyframes, sensors::Calibration* calibration,
                    const KeyframeWheelOptions& options = {});

struct KeyframeGnssOptions {
  factors::LossOptions loss = factors::FactorLossOptions().gnss;  // Cauchy, 3 sigma (multipath)
  // Largest spacing of the fixes bracketing t_k (outages get no factor); 0: Eq. T1 from the
  // fixes' own stamps (0.25 s for a 10 Hz receiver, 2.5 s for 1 Hz), as the offline calibration
  // derives it.
  double max_fix_gap_s = 0.0;
  bool estimate_lever_arm = true;     // else p_I_A is set constant
  bool estimate_time_offset = false;  // time_offset_gnss_imu_s (Eq. K16); else held
  double gravity_m_s2 = 9.80665;      // as KeyframeWheelOptions::gravity_m_s2
  // With a clock offset: the largest spacing of the IMU samples that carry a keyframe's state
  // to its fix (Eq. K16); a keyframe in an IMU dropout gets no factor. 0: Eq. T1 from the IMU's
  // stamps.
  double max_imu_gap_s = 0.0;
  // The fixes' std scaled per axis group: their scatter when it exceeds their stated std
  // (estimation/gnss_noise.h, Eq. N2).
  GnssStdScale noise_scale;
};

// The antenna position in ENU at t_ns (Eq. K1) with its interpolated per-axis sigma (Eq. K2);
// false when no two fixes within max_fix_gap_s bracket t_ns (a fix exactly at t_ns is used
// alone). Throws autocal::Error for fix stamps that do not increase, a non-positive gap or a
// fix the converter rejects.
bool InterpolateGnss(const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
                     int64_t t_ns, double max_fix_gap_s, factors::GnssMeasurement* measurement);

// Adds a GnssFactor (Eq. F30) per keyframe with an interpolated fix, on its q_W_I, p_W_I and
// the calibration's p_I_A: two residual blocks under the loss, the horizontal rows and the
// vertical row (factors::GnssAxes). With a GNSS clock offset each keyframe takes its nearest fix
// instead, within max_fix_gap_s / 2, no fix serving two, as the wheels' samples (Eq. K16,
// K17); without one, where a fix would enter two keyframes' interpolated rows (keyframes denser
// than the fixes, or as dense but off their stamps: the rows would count a fix several times,
// or scatter below their sigma and miss a curving antenna), each fix serves its nearest keyframe
// once, a keyframe perhaps several. Its v_W_I, b_g, b_a and the offset block then enter the
// factor; `imu` carries the state to the fix. Returns the number of keyframes with a fix
// (ownership as AddWheelFactors). Throws autocal::Error as
// InterpolateGnss, or for a keyframe q_W_I missing from the problem or without a manifold.
int AddGnssFactors(ceres::Problem* problem, const sensors::ImuSamples& imu,
                   const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
                   std::vector<Keyframe>* keyframes, sensors::Calibration* calibration,
                   const KeyframeGnssOptions& options = {});

// Eq. N2 (estimation/gnss_noise.h) over the GNSS rows AddGnssFactors adds with `options`,
// whitened by the fixes' stated std (options.noise_scale is not applied), at the keyframes' and
// the calibration's values, which are only read. Throws autocal::Error as AddGnssFactors, or
// when a row is not finite there.
GnssNoiseFromResiduals MeasureGnssNoise(const sensors::ImuSamples& imu,
                                        const sensors::GnssFixes& fixes,
                                        const sensors::EnuConverter& converter,
                                        std::vector<Keyframe>* keyframes,
                                        sensors::Calibration* calibration,
                                        const KeyframeGnssOptions& options);

struct GnssAlignmentOptions {
  double max_fix_gap_s = 0.0;  // as KeyframeGnssOptions::max_fix_gap_s (0: from the stamps)
  // Refits after dropping pairs farther than max(min_outlier_distance_m, outlier_mad_factor *
  // 1.4826 * median distance) from their fix (multipath).
  int max_refits = 3;
  double outlier_mad_factor = 5.0;
  double min_outlier_distance_m = 0.5;
  // Least horizontal RMS distance of the pairs from their centroid (the yaw is as good as fix
  // noise over that extent).
  double min_horizontal_extent_m = 5.0;
};

struct GnssAlignment {
  double yaw_rad = 0.0;                                     // rotation about z_W applied
  Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();  // then this shift (Eq. K5)
  int num_pairs = 0;                                        // keyframes with an interpolated fix
  int num_inliers = 0;                                      // pairs used by the last fit
  double rms_m = 0.0;  // RMS antenna-to-fix distance of the inliers after alignment
};

// The fixes with their stamps moved onto the IMU clock, t_imu = t_fix + time_offset_gnss_imu_s.
// AlignKeyframesToGnss, RemoveOdometryDrift and PlaceKeyframesOnGnss pair fixes with keyframes
// by stamp, so they take fixes on the IMU clock: a fix stamped 0.15 s early, paired as it is,
// puts the antenna 2.25 m along the track at 15 m/s. (The GNSS factors apply the offset
// themselves and take the fixes as logged.)
sensors::GnssFixes FixesOnImuClock(sensors::GnssFixes fixes, double time_offset_gnss_imu_s);

// 4-DoF alignment (yaw about gravity and a translation, Eqs. K3-K5) of keyframes in a
// gravity-aligned frame to ENU: their antenna positions are fitted to the fixes (on the IMU
// clock, FixesOnImuClock) interpolated at the keyframe times and every state is moved (biases
// stay). Throws autocal::Error with
// fewer than two pairs, inliers spread less than min_horizontal_extent_m, or as InterpolateGnss.
GnssAlignment AlignKeyframesToGnss(std::vector<Keyframe>* keyframes,
                                   const sensors::GnssFixes& fixes,
                                   const sensors::EnuConverter& converter,
                                   const Eigen::Vector3d& p_I_A,
                                   const GnssAlignmentOptions& options = {});

struct OdometryDriftOptions {
  double max_fix_gap_s = 0.0;  // as GnssAlignmentOptions::max_fix_gap_s
  // A keyframe's correction is a line fitted to the antenna-to-fix differences within this half
  // window, at its time: the odometry drifts over minutes, the fixes' noise and multipath change
  // over seconds.
  double half_window_s = 5.0;
  int min_pairs = 5;  // fewer in a window: the correction of the nearest keyframe that has one
  // The line is fitted again without the pairs farther from it than max(min_outlier_distance_m,
  // outlier_mad_factor * 1.4826 * median distance), as GnssAlignmentOptions.
  double outlier_mad_factor = 5.0;
  double min_outlier_distance_m = 0.5;
};

struct OdometryDrift {
  int num_pairs = 0;             // keyframes with an interpolated fix
  double median_before_m = 0.0;  // median antenna-to-fix distance over the pairs, before
  double median_after_m = 0.0;   // and after the correction
  double max_correction_m = 0.0;
};

// Eq. K5b: after AlignKeyframesToGnss, what is left of an odometry track's drift against the
// fixes (on the IMU clock, FixesOnImuClock) is taken out of the keyframes' positions, a keyframe
// moved by a line fitted (robustly, per axis) to the antenna-to-fix differences within
// half_window_s of it, at its time: a drift's local rate, so that an outage on one side of a window
// does not bias it. Attitudes, velocities and biases stay: the correction changes over minutes, so
// the track's shape over a few seconds (what the LiDAR's partner sweeps see) keeps. Without any
// window of min_pairs pairs nothing moves. Throws autocal::Error as InterpolateGnss, or for a
// non-positive half window.
OdometryDrift RemoveOdometryDrift(std::vector<Keyframe>* keyframes, const sensors::GnssFixes& fixes,
                                  const sensors::EnuConverter& converter,
                                  const Eigen::Vector3d& p_I_A,
                                  const OdometryDriftOptions& options = {});

struct GnssPlacementOptions {
  // The fixes within this half-width of a keyframe's time give its antenna track (Eq. K7), with
  // outliers rejected as GnssAlignmentOptions; 0: Eq. T3 from the fixes' stamps (1 s for 1-10 Hz
  // receivers, 5 s for 0.5 Hz), as the offline calibration derives it.
  double half_width_s = 0.0;
  int min_fixes = 5;  // fewer inliers in the window: the keyframe is left to its neighbours
  int max_refits = 3;
  double outlier_mad_factor = 5.0;
  double min_outlier_distance_m = 0.5;
  // A keyframe's track heading enters the yaw (Eq. K8) when its horizontal speed exceeds this
  // many sigmas of its fitted velocity (Eq. K10).
  double heading_sigmas = 5.0;
  // With fewer headings the yaw comes from the track's geometry (Eq. K11) when its net travel
  // exceeds max(min_track_travel_m, heading_sigmas * sqrt(2) * median horizontal fix sigma).
  int min_headings = 5;
  double min_track_travel_m = 5.0;
  // A heading is compared with the headings within this half window (Eq. K8), and a keyframe
  // without one takes its yaw from those within it of the nearest keyframes with one (Eq. K9b):
  // the gyro's yaw that turns the keyframes relative to each other drifts with its bias
  // between them (0.025 rad over 5 s at 5e-3 rad/s), not over the whole log.
  double heading_window_s = 5.0;
};

struct GnssPlacement {
  double yaw_rad = 0.0;       // rotation about z_W applied to every keyframe (Eq. K8)
  int num_placed = 0;         // keyframes placed on their own fitted track
  int num_bridged = 0;        // keyframes without one, interpolated from placed neighbours
  std::vector<bool> placed;   // per keyframe: on its own track (else bridged)
  std::vector<bool> heading;  // per keyframe: its heading entered the yaw (Eq. K10)
  // Per keyframe: the 1-sigma of its fitted velocity per horizontal axis (Eq. K10; infinity
  // for a bridged one), so that a heading's 1-sigma is this over the speed.
  std::vector<double> velocity_sigma_m_s;
  int num_headings = 0;          // keyframes whose heading entered the yaw
  double heading_rms_rad = 0.0;  // RMS of their headings about the ones around them (Eq. K8)
  bool yaw_from_track_geometry = false;  // Eq. K11 (too few headings)
};

// Positions, velocities and yaw from GNSS alone, for keyframes the LiDAR odometry could not
// place (docs/keyframe_factors.md, "Keyframes from GNSS and the IMU"): each is put on the
// antenna track fitted around it (Eq. K7; the fixes on the IMU clock, FixesOnImuClock) and all are
// turned by one yaw from the track headings (Eq. K8: those that agree with the headings around
// them, so that keyframes whose relative yaw drifts over the log keep theirs) or the track's
// travel (Eq. K11); roll, pitch and biases stay. Keyframes in outages are interpolated between
// placed ones (at the ends, moved at the nearest one's velocity). Throws autocal::Error when fewer
// than two keyframes can be placed, when neither headings nor travel give the yaw (the message
// gives the figures), or as InterpolateGnss.
GnssPlacement PlaceKeyframesOnGnss(std::vector<Keyframe>* keyframes,
                                   const sensors::GnssFixes& fixes,
                                   const sensors::EnuConverter& converter,
                                   const Eigen::Vector3d& p_I_A, const Eigen::Quaterniond& q_I_V,
                                   const GnssPlacementOptions& options = {});

}  // namespace estimation
}  // namespace autocal
