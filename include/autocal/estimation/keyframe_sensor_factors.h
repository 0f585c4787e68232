#pragma once

// IMU, wheel and GNSS factors attached to batch keyframes (docs/keyframe_factors.md).
//
// A batch problem has one Keyframe per LiDAR sweep. Wheel and GNSS measurements do not fall
// on keyframe instants, so each keyframe gets one factor from the measurements linearly
// interpolated to its time t_k (Eq. K1) between the two samples bracketing it:
//   x(t_k) = (1 - s) x_0 + s x_1,   s = (t_k - t_0) / (t_1 - t_0),
// and none when those samples are farther apart than a maximum gap (dropouts, GNSS outages).
//
// With GNSS factors, W is the ENU frame at the converter's origin: the fixes anchor position
// and yaw, so no keyframe needs to be held for the gauge. A trajectory from an initializer
// lives in its own gravity-aligned frame; AlignKeyframesToGnss moves it into ENU first.
//
// Quaternion blocks (each keyframe's q_W_I, the calibration's q_I_V) must already be in the
// problem with geometry::RightQuaternionManifold; the functions add every other block they use.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <cstdint>
#include <vector>

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

// Adds one ImuFactor (Eq. F10) between each pair of consecutive keyframes, preintegrated
// from the IMU samples at the first keyframe's biases. Returns the number added. Ownership as
// AddWheelFactors. Throws autocal::Error when the samples do not cover the keyframes or the
// keyframe times do not increase, or for a keyframe q_W_I missing from the problem or without
// a manifold.
int AddImuFactors(ceres::Problem* problem, const sensors::ImuSamples& imu,
                  std::vector<Keyframe>* keyframes, const KeyframeImuOptions& options);

// Adds a prior at zero on the keyframe's gyro and accelerometer biases (Eq. F41, 1-sigma
// per axis), as a problem without other bias information needs on its first keyframe.
// Ownership as AddWheelFactors.
void AddBiasPriors(ceres::Problem* problem, Keyframe* keyframe, double gyro_bias_sigma_rad_s,
                   double accel_bias_sigma_m_s2);

// Eq. K6 (docs/keyframe_factors.md): a model error correlated over tau_s seen every dt_s
// carries the information of about T / (2 tau) independent samples, not T / dt; the factor
// sqrt(max(1, 2 tau / dt)) on each row's sigma leaves the information of a drive at the former.
// 1 for tau_s = 0 (white rows) or a non-positive dt_s.
double NonHolonomicSigmaScale(double tau_s, double dt_s);

struct KeyframeWheelOptions {
  // Sigmas and rows of each factor. With factor.shared_radius the left radius block
  // (Calibration::wheel_radius_left_m) stands for both wheels; the right one is not touched.
  factors::WheelFactorOptions factor;
  factors::LossOptions loss = factors::FactorLossOptions().wheel;  // Huber, 2 sigma
  // A keyframe whose bracketing wheel samples are farther apart than this gets no factor (one
  // lost sample is bridged, a dropout is not). The default is Eq. T1 (sensors/sample_timing.h)
  // for a 100 Hz encoder; the offline calibration derives it from the log's stamps.
  double max_wheel_gap_s = 0.025;
  // The same for the IMU samples that give the raw gyro at the keyframe (Eq. T1 at 200 Hz;
  // derived from the log as above).
  double max_imu_gap_s = 0.0125;
  // The rows take the mean gyro over this span around t_k (Eq. K10): a single interpolated
  // sample carries the gyro's white noise into the lever-arm term w x p_I_V (1.8 cm/s per
  // 0.01 rad/s at 1.8 m), which pulled a straight drive's mount pitch 1-2 deg off at a stated
  // 0.3 deg. 0 (the default) takes the interpolated sample, exact for noise-free data; the
  // offline calibration uses 0.2 s.
  double gyro_mean_span_s = 0.0;
  // 1-sigma of one gyro sample (density * sqrt(rate)); the mean's noise, over sqrt(n), is added
  // to the rows' sigma through the lever arm (Eq. K10). 0 adds nothing.
  double gyro_sample_sigma_rad_s = 0.0;
  // Correlation time of the non-holonomic rows' model error (Eq. K6): the rear axle's
  // lateral and vertical speed in the vehicle frame is not white noise but follows the body's
  // roll and pitch on its suspension, which follow the acceleration. The rows' sigma is scaled
  // by sqrt(2 tau / dt), dt the mean keyframe spacing; 0 treats the rows as white. The default
  // is the autocorrelation integral of the simulated vertical speed up to its first zero; over
  // +-10 s it is 0.25 s (a speed that follows the acceleration has a negative lobe), and the
  // consistency suite finds 2 s cautious (docs/keyframe_factors.md).
  double non_holonomic_correlation_s = 2.0;
  // Blocks not estimated are set constant in the problem (blocks left estimated are not
  // made variable: a caller may have fixed them).
  bool estimate_vehicle_rotation = true;     // q_I_V
  bool estimate_vehicle_translation = true;  // p_I_V
  bool estimate_radii = true;
  bool estimate_track_width = true;
  // Estimate Calibration::time_offset_wheel_imu_s (Eq. K9). When false the offset is held at
  // its value; at 0 the wheel samples are read at t_k as before (Eq. K1).
  bool estimate_time_offset = false;
};

// Adds one WheelFactor (Eq. F22) per keyframe whose time both the wheel samples and the IMU
// samples bracket within the maximum gaps: wheel rates and raw gyro interpolated to t_k
// (Eq. K1). With a wheel clock offset (Calibration::time_offset_wheel_imu_s nonzero, or
// options.estimate_time_offset) the wheel values are read at t_k - offset instead (Eq. K9,
// the gyro stays at t_k) and the offset block enters every factor; the gap rule then applies
// to the samples around t_k - offset. Factors on the keyframe's q_W_I, v_W_I, b_g (the factor
// removes b_g from the gyro) and the calibration's q_I_V, p_I_V, radii and track width. A standing
// car gives zero rates: its factors carry no radius information but tie the keyframe's velocity to
// zero. The keyframes and the calibration must outlive the problem (their members are the blocks);
// the problem takes ownership of the cost and loss functions (Problem::Options defaults).
// Returns the number of factors added. Throws autocal::Error for stamps that do not increase,
// non-positive gaps, or a quaternion block missing from the problem or without a manifold.
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
};

// The same for any form: WheelFactor on the radii and track width for angular rates,
// WheelSpeedResidual (Eq. F25) on the speed scales and track width for linear speeds,
// OdometryTwistResidual (Eq. F26) on odometry_speed_scale and effective_track_m for speed and
// yaw rate. options.factor carries the form's sigmas (WheelFactorOptions::FromEncoderNoise,
// FromWheelSpeedNoise, FromOdometryNoise); estimate_radii holds or frees the form's scales
// (radii, speed scales, k_v), estimate_track_width its track (b or b_eff). Throws as above,
// and for a non-positive controller track.
int AddWheelFactors(ceres::Problem* problem, const sensors::ImuSamples& imu, const WheelData& wheel,
                    std::vector<Keyframe>* keyframes, sensors::Calibration* calibration,
                    const KeyframeWheelOptions& options = {});

struct KeyframeGnssOptions {
  factors::LossOptions loss = factors::FactorLossOptions().gnss;  // Cauchy, 3 sigma (multipath)
  // A keyframe whose bracketing fixes are farther apart than this gets no factor (outages).
  // The default is Eq. T1 (sensors/sample_timing.h) for a 10 Hz receiver (2.5 s at 1 Hz); the
  // offline calibration derives it from the log's stamps.
  double max_fix_gap_s = 0.25;
  bool estimate_lever_arm = true;  // else p_I_A is set constant
  // Estimate Calibration::time_offset_gnss_imu_s (Eq. K9). When false the offset is held at
  // its value; at 0 the fixes are read at t_k as before (Eq. K1).
  bool estimate_time_offset = false;
};

// The antenna position in ENU at t_ns (Eq. K1 on the fixes converted by `converter`) with the
// linearly interpolated per-axis sigma (Eq. K2). Returns false when no two fixes within
// max_fix_gap_s bracket t_ns (a fix exactly at t_ns is used alone).
// Throws autocal::Error for fix stamps that do not increase, a non-positive gap or a fix
// the converter rejects.
bool InterpolateGnss(const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
                     int64_t t_ns, double max_fix_gap_s, factors::GnssMeasurement* measurement);

// Adds one GnssFactor (Eq. F30) per keyframe with an interpolated fix (InterpolateGnss), on
// the keyframe's q_W_I, p_W_I and the calibration's p_I_A. With a GNSS clock offset
// (Calibration::time_offset_gnss_imu_s nonzero, or options.estimate_time_offset) the fixes are
// read at t_k - offset (Eq. K9) and the offset block enters every factor. Returns the number added.
// Ownership as AddWheelFactors. Throws autocal::Error as InterpolateGnss, for a non-positive
// gap, a keyframe q_W_I missing from the problem or without a manifold, or an invalid fix.
int AddGnssFactors(ceres::Problem* problem, const sensors::GnssFixes& fixes,
                   const sensors::EnuConverter& converter, std::vector<Keyframe>* keyframes,
                   sensors::Calibration* calibration, const KeyframeGnssOptions& options = {});

struct GnssAlignmentOptions {
  double max_fix_gap_s = 0.25;  // as KeyframeGnssOptions::max_fix_gap_s (derived likewise)
  // Multipath outliers would pull a plain least-squares fit: after each fit, pairs farther
  // than max(min_outlier_distance_m, outlier_mad_factor * 1.4826 * median distance) from
  // their fix are dropped and the fit is repeated, at most this many times.
  int max_refits = 3;
  double outlier_mad_factor = 5.0;
  double min_outlier_distance_m = 0.5;
  // The yaw is only as good as fix noise over the horizontal extent of the pairs: below this
  // RMS distance from their centroid the alignment is refused.
  double min_horizontal_extent_m = 5.0;
};

struct GnssAlignment {
  double yaw_rad = 0.0;                                     // rotation about z_W applied
  Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();  // then this shift (Eq. K5)
  int num_pairs = 0;                                        // keyframes with an interpolated fix
  int num_inliers = 0;                                      // pairs used by the last fit
  double rms_m = 0.0;  // RMS antenna-to-fix distance of the inliers after alignment
};

// 4-DoF alignment (yaw about the gravity axis and a translation, Eqs. K3-K5) of keyframes in a
// gravity-aligned frame to ENU: the antenna positions p_W_I + R_W_I p_I_A are fitted by least
// squares to the fixes interpolated at the keyframe times, and every keyframe state is moved
// (q <- R_z q, p <- R_z p + t, v <- R_z v; biases are body-frame and stay).
// Throws autocal::Error with fewer than two pairs, inliers spread less than
// min_horizontal_extent_m horizontally (yaw unobservable), or as InterpolateGnss.
GnssAlignment AlignKeyframesToGnss(std::vector<Keyframe>* keyframes,
                                   const sensors::GnssFixes& fixes,
                                   const sensors::EnuConverter& converter,
                                   const Eigen::Vector3d& p_I_A,
                                   const GnssAlignmentOptions& options = {});

struct GnssPlacementOptions {
  // The antenna track around a keyframe: the fixes within this half-width of its time, fitted
  // per axis by a quadratic in time (Eq. K7) with outlier rejection as GnssAlignmentOptions.
  // The default is Eq. T3 (sensors/sample_timing.h) for 1-10 Hz receivers; the offline
  // calibration derives it from the log's stamps (2.5 s at 1 Hz).
  double half_width_s = 1.0;
  int min_fixes = 5;  // fewer inliers in the window: the keyframe is left to its neighbours
  int max_refits = 3;
  double outlier_mad_factor = 5.0;
  double min_outlier_distance_m = 0.5;
  // A keyframe's track heading enters the yaw (Eq. K8) when its horizontal speed exceeds this
  // many sigmas of its fitted velocity (Eq. K10, from the fixes' sigmas and the window): at 5
  // a heading is rarely noise, whatever the platform's speed or the receiver's accuracy.
  double heading_sigmas = 5.0;
  // With fewer keyframes with a heading, the yaw comes from the whole track's geometry
  // (Eq. K11) when its net travel along the vehicle's heading exceeds
  // max(min_track_travel_m, heading_sigmas * sqrt(2) * the fixes' median horizontal sigma).
  int min_headings = 5;
  double min_track_travel_m = 5.0;
};

struct GnssPlacement {
  double yaw_rad = 0.0;      // rotation about z_W applied to every keyframe (Eq. K8)
  int num_placed = 0;        // keyframes placed on their own fitted track
  int num_bridged = 0;       // keyframes without one, interpolated from placed neighbours
  std::vector<bool> placed;  // per keyframe: on its own track (else bridged)
  // Per keyframe: its track heading is trusted (Eq. K10; none when the yaw came from the
  // track's geometry).
  std::vector<bool> heading;
  int num_headings = 0;                  // keyframes whose heading entered the yaw
  double heading_rms_rad = 0.0;          // RMS heading residual of those after the yaw
  bool yaw_from_track_geometry = false;  // Eq. K11 (too few headings)
};

// For keyframes whose positions the LiDAR odometry could not determine (a featureless road,
// or traffic moving with the car), positions and velocities from GNSS alone: the antenna
// track fitted around each keyframe (Eq. K7) gives p_W_A and v_W_A, the yaw about gravity
// comes from the track heading against the vehicle's forward axis R_W_I R_I_V x (Eq. K8) of
// the keyframes whose speed stands out of their fitted velocity's noise (Eq. K10), or, with
// fewer than min_headings of those (a slow platform, noisy fixes), from the whole track's
// travel against the keyframes' forward axes (Eq. K11); every keyframe becomes
// q <- R_z q, p <- p_W_A - R_W_I p_I_A, v <- v_W_A. Roll, pitch and the biases are the
// initializer's. Keyframes without a fitted track (outages) are interpolated between the
// nearest placed ones (or moved with the nearest one's velocity at the ends). Throws
// autocal::Error when fewer than two keyframes can be placed, when neither the headings nor
// the track's travel give the yaw (the message gives the speeds, sigmas and travel), or as
// InterpolateGnss.
GnssPlacement PlaceKeyframesOnGnss(std::vector<Keyframe>* keyframes,
                                   const sensors::GnssFixes& fixes,
                                   const sensors::EnuConverter& converter,
                                   const Eigen::Vector3d& p_I_A, const Eigen::Quaterniond& q_I_V,
                                   const GnssPlacementOptions& options = {});

}  // namespace estimation
}  // namespace autocal
