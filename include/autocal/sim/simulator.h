#pragma once

// The sensor simulator: turns a scenario (drive + world) and a true calibration into the
// measurements of an IMU, a spinning LiDAR, rear-wheel encoders and a GNSS receiver, with
// ground truth, in memory (Simulator, Simulate) or as a dataset directory (WriteDataset).
// Noise models and what is exact are described in docs/simulator.md.
//
// Clocks: the IMU clock is the reference; the trajectory time t_s is seconds since
// start_time_ns on that clock. Every other sensor stamps on its own clock with the
// project's convention t_imu = t_sensor + offset: a wheel sample stamped t was measured at
// IMU time t + time_offset_wheel_imu_s, a GNSS fix at t + time_offset_gnss_imu_s, a LiDAR
// point stamped t_sweep + tau at t_sweep + tau + time_offset_lidar_imu_s (burst delivery
// of wheel samples adds a delay on top, see WheelSimOptions).

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "autocal/io/dataset.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/measurements.h"
#include "autocal/sensors/sensor_config.h"
#include "autocal/sim/scenario.h"

namespace autocal {
namespace sim {

struct ImuSimOptions {
  // Off: exact body rate and specific force (no white noise, no bias); the densities below
  // are still what sensors.yaml reports.
  bool add_noise = true;
  // Continuous-time densities (Kalibr names); the simulated noise is these times noise_scale,
  // and sensors.yaml states the scaled values.
  sensors::ImuNoise noise;
  double noise_scale = 1.0;
  // The random walks' scale when it differs from noise_scale: vibration raises the white
  // noise of a mounted IMU, not its bias instability.
  std::optional<double> random_walk_scale;
  double RandomWalkScale() const { return random_walk_scale.value_or(noise_scale); }
  // Turn-on biases are drawn per axis from N(0, sigma^2), then random-walk.
  double initial_gyro_bias_sigma_rad_s = 2e-3;
  double initial_accel_bias_sigma_m_s2 = 3e-2;
  double gravity_m_s2 = 9.80665;
  // The rate is noise.update_rate_hz (20-2000 Hz). Irregular sampling: each sample instant
  // moves from its grid point by a uniform draw in [-stamp_jitter_s, +stamp_jitter_s]
  // (below 0.4 periods) and is the truth at its stamp.
  double stamp_jitter_s = 0.0;
};

struct LidarSimOptions {
  bool enabled = true;
  // Beams are spread evenly between the configured elevations; range_noise_m is the 1-sigma
  // of Gaussian range noise.
  sensors::LidarConfig config;
  bool add_noise = true;              // range noise on/off (config.range_noise_m is reported)
  double dropout_probability = 0.02;  // returns lost at random
  // Each sweep stamped when it ends, its points' times before the stamp (negative), as some
  // drivers write them; otherwise when it starts. The points are the same either way.
  bool stamp_at_end = false;
};

// Rear-wheel angular rates (v -+ omega b / 2) / r from the true speed v and yaw rate omega of
// V, with b the calibration's track width: for a skid-steer platform that is the effective
// (slip) track, wider than the physical one (docs/simulator.md, "Wheels"). config.form picks
// what the dataset carries: those rates (wheel.csv), rear-wheel speeds (v -+ omega b / 2) / s
// with the true speed scales s (wheel_speed.csv), or the odometry twist v / k_v and
// omega b_eff / (k_v b_ctrl) with the true odometry_speed_scale k_v and effective_track_m
// b_eff (odometry.csv; b_ctrl is config.controller_track_m, else the nominal effective track).
// The wheel defaults of a road car as its sensors.yaml states them: the encoder defaults and a
// passenger car's rear-axle slip (docs/keyframe_factors.md, Eq. K6c), a cornering compliance
// of 0.3 deg/(m/s^2) and 1 cm/s driving straight (a 2 % road crown's 0.2 m/s^2 sideways at that
// compliance is 0.06 deg of slip, 1 cm/s at 10 m/s). Simulator::sensors_config() states at least
// the simulated VehicleDynamicsOptions::rear_slip_per_lateral_accel.
sensors::WheelConfig RoadCarWheelConfig();
// A skid steer's statement: it slides sideways in every turn, so its slip keeps the platform
// defaults of sensors::WheelConfig, not a road car's; the other fields of *config stay.
void StateSkidSteerSlip(sensors::WheelConfig* config);

struct WheelSimOptions {
  bool enabled = true;
  // Rate, form and 1-sigma noise: noise_rad_s of each wheel rate, noise_m_s of each wheel
  // speed or of the odometry speed, yaw_rate_noise_rad_s of the odometry yaw rate; the rear
  // axle's stated slip.
  sensors::WheelConfig config = RoadCarWheelConfig();
  bool add_noise = true;
  // Clock: a sample stamped t on the wheel clock was measured at IMU time t + offset.
  double time_offset_wheel_imu_s = 0.0;
  // Irregular sampling as for the IMU: measurement instants move by U(-jitter, +jitter).
  double stamp_jitter_s = 0.0;
  // Burst delivery (a CAN bus read in groups): the measurements are delivered in groups of
  // burst_size consecutive ones, released when the last of the group is measured; sample j
  // of a group (j = 0 .. burst_size - 1) is stamped at arrival, release + j * burst_span_s /
  // burst_size. A stamp then runs late on its measurement by (burst_size - 1 - j) periods
  // plus j * burst_span_s / burst_size. 1: off.
  int burst_size = 1;
  double burst_span_s = 0.002;
  // Each sample is lost with this probability (a gap in the log, not a zero reading).
  double drop_probability = 0.0;
};

struct GnssSimOptions {
  bool enabled = true;
  sensors::GnssConfig config;  // rate_hz in (0, 100]
  // Clock: a fix stamped t on the receiver's clock is the antenna position at IMU time
  // t + offset (a receiver stamping 0.2 s after the fix: -0.2).
  double time_offset_gnss_imu_s = 0.0;
  // Receiver-reported 1-sigma (east, north, up); each fix scales it by a factor in [1, 2]
  // that drifts slowly, and the error is drawn with the reported sigma.
  Eigen::Vector3d std_enu_m = Eigen::Vector3d(0.03, 0.03, 0.06);
  // Correlation time of the errors, s: each axis's error (in units of the reported sigma) is
  // a first-order Gauss-Markov process, e_k = a e_(k-1) + sqrt(1 - a^2) n_k with
  // a = exp(-dt / tau), so the reported sigma stays the error's marginal sigma while
  // neighbouring fixes err alike, as a real receiver's do. 0: independent errors.
  double error_correlation_time_s = 0.0;
  bool add_noise = true;  // off: fixes are exact (sigma is still reported)
  // Outages: this many gaps without fixes, each outage_duration_s long, placed at random.
  int num_outages = 2;
  double outage_duration_s = 4.0;
  // Multipath outliers: with this probability a fix is off by 3-15 m horizontally and up to
  // 5 m vertically while reporting the normal sigma.
  double outlier_probability = 0.02;
  // Geodetic origin of W (WGS84, ellipsoidal height): Karlsruhe, Germany.
  double origin_lat_deg = 49.0110;
  double origin_lon_deg = 8.4170;
  double origin_alt_m = 165.0;
};

// How far sensors.yaml's nominal calibration is from the truth (per-axis 1-sigma of a
// seeded Gaussian draw). Wheel radii and track width are nominal values by design (the
// truth is ~1% off them, see DefaultTrueCalibration); their stated sigmas cover that.
// With state_uncertainty, sensors.yaml states these sigmas as the nominal calibration's
// uncertainty, as a calibration engineer would from the drawings and the mounting tolerance
// (the offline calibration uses them as prior widths, docs/calibration.md).
struct NominalPerturbation {
  double rotation_deg = 1.5;    // T_I_L and T_I_V, per axis
  double translation_m = 0.03;  // p_I_L, p_I_V and p_I_A, per axis
  double time_offset_s = 0.004;
  double wheel_radius_sigma_m = 0.005;  // stated only; 0.33 m vs the true 0.3335 / 0.3326 m
  double track_width_sigma_m = 0.03;    // stated only; 1.60 m vs the true 1.62 m
  bool state_uncertainty = true;
  // When set, sensors.yaml's q_I_V is this rotation instead of a draw around the truth (a
  // mount guessed from drawings, possibly far off), stated with q_I_V_sigma_deg per axis.
  std::optional<Eigen::Quaterniond> q_I_V;
  double q_I_V_sigma_deg = 30.0;
};

// LiDAR 0.55 m above and 0.3 m ahead of the IMU, rotated (2, -3, 4) deg (roll, pitch, yaw);
// time offset 25 ms; IMU 1.3 m ahead of the rear axle, 1.2 m up, rotated (0.3, -0.5, 1) deg;
// rear wheel radii 0.3335 m (left) and 0.3326 m (right) for a nominal 0.33 m; track width
// 1.62 m for a nominal 1.60 m; antenna 1.2 m behind and 0.65 m above the IMU.
sensors::Calibration DefaultTrueCalibration();

// The calibration with the IMU turned to q_V_I in the vehicle, its origin in V kept, and
// the LiDAR and the GNSS antenna left where they are in V (T_I_L and p_I_A re-expressed):
// any mounting (e.g. y-up or z-down) without moving the other sensors.
sensors::Calibration WithImuMount(const sensors::Calibration& calibration,
                                  const Eigen::Quaterniond& q_V_I);

// Rotation from roll, pitch, yaw in degrees: Rz(yaw) Ry(pitch) Rx(roll).
Eigen::Quaterniond RotationFromRollPitchYawDeg(double roll_deg, double pitch_deg, double yaw_deg);

struct SimulationOptions {
  ScenarioType scenario = ScenarioType::kUrban;
  double duration_s = 60.0;
  uint64_t seed = 1;
  // IMU-clock stamp of t_s = 0 (an epoch-sized stamp, as real logs have).
  int64_t start_time_ns = 1'700'000'000'000'000'000;
  VehicleDynamicsOptions dynamics;
  ImuSimOptions imu;
  LidarSimOptions lidar;
  WheelSimOptions wheel;
  GnssSimOptions gnss;
  sensors::Calibration true_calibration = DefaultTrueCalibration();
  NominalPerturbation nominal_perturbation;
  double nominal_wheel_radius_m = 0.33;
  double nominal_track_width_m = 1.60;

  // The same options with every random effect off (add_noise = false everywhere, no LiDAR
  // dropouts, no GNSS outliers). Outages stay: they are not noise; so do stamp jitter,
  // bursts and lost wheel samples (they are timing, not measurement noise).
  SimulationOptions WithoutNoise() const;
};

// The beams of a common spinning LiDAR with `num_beams` of them, evenly spread: 16 over
// -15..15 deg (a VLP-16), 32 over -25..15 deg (the default), 64 over -24.8..2 deg (an
// HDL-64E). Sets num_beams and the elevations of *config; any other count throws
// autocal::Error naming the three.
void SetSpinningLidarBeams(int num_beams, sensors::LidarConfig* config);

// Platforms after real logs (docs/simulator.md, "Presets"); change any field afterwards.
// A slow skid-steer robot: skid_steer scenario, 300 s, IMU at 30 Hz mounted y-up
// (R_V_I = Rz(-90 deg) Rx(+90 deg), 1 deg off), wheel odometry at 10 Hz with 10 ms jitter
// and 2 % lost samples lagging the IMU by 0.38 s, an effective track 1.875 times the
// physical 0.555 m, GPS at 2.5 Hz with ~1 m sigma, no LiDAR. The nominal mount is the
// exact y-up one and the nominal track the physical one.
SimulationOptions SkidSteerRobotOptions();
// A car with a phone-grade IMU at 104 Hz mounted x forward, y right, z down (R_V_I =
// Rx(180 deg), 1 deg off), CAN wheel rates at 83 Hz delivered in bursts of 4, GNSS at 10 Hz
// stamped 0.2 s after the fix, on the straight scenario (60 s), no LiDAR.
SimulationOptions CanBusCarOptions();

// The IMU log with its truth: samples, the true biases at each sample and T_W_I, v_W_I.
struct ImuLog {
  sensors::ImuSamples samples;
  std::vector<Eigen::Vector3d> gyro_bias;
  std::vector<Eigen::Vector3d> accel_bias;
  io::Trajectory truth;
};

// The wheel log with its truth per delivered sample: the IMU-clock instant it was measured
// at (the stamp plus the offset, minus the burst delay), and the true forward speed of V's
// origin and yaw rate of V then (the inputs of every wheel data form).
struct WheelLog {
  sensors::WheelSamples samples;
  std::vector<int64_t> true_t_ns;  // IMU clock
  std::vector<double> speed_m_s;
  std::vector<double> yaw_rate_rad_s;
};

struct GnssLog {
  sensors::GnssFixes fixes;
  std::vector<bool> is_outlier;                      // per fix
  std::vector<Eigen::Vector3d> true_p_W_A;           // true antenna position per fix
  std::vector<std::pair<double, double>> outages_s;  // [begin, end) in trajectory time
};

class Simulator {
 public:
  // Validates the options (throws autocal::Error naming the bad field) and builds the
  // scenario and the nominal calibration.
  explicit Simulator(const SimulationOptions& options);

  const SimulationOptions& options() const { return options_; }
  const Scenario& scenario() const { return scenario_; }
  const sensors::Calibration& true_calibration() const { return options_.true_calibration; }
  const sensors::Calibration& nominal_calibration() const { return nominal_; }
  // sensors.yaml content: rates, the IMU noise actually simulated, nominal calibration.
  io::SensorsConfig sensors_config() const;

  // IMU-clock stamp of trajectory time t_s, and back.
  int64_t StampAt(double t_s) const;
  double TimeOf(int64_t t_ns) const;
  // True T_W_I at trajectory time t_s.
  geometry::Pose3d ImuPoseAt(double t_s) const;

  ImuLog GenerateImu() const;
  WheelLog GenerateWheelLog() const;
  sensors::WheelSamples GenerateWheel() const { return GenerateWheelLog().samples; }
  // The log's samples in the other wheel forms (WheelSimOptions), same stamps, own noise.
  sensors::WheelSpeedSamples WheelSpeedsOf(const WheelLog& log) const;
  sensors::OdometrySamples OdometryOf(const WheelLog& log) const;
  GnssLog GenerateGnss() const;

  // Sweeps are generated one at a time (each from its own random stream, so any subset is
  // reproducible): stamps on the LiDAR clock, points in L with per-point time.
  int num_sweeps() const { return num_sweeps_; }
  int64_t SweepStamp(int index) const;
  lidar::LidarSweep GenerateSweep(int index) const;
  // The unit direction in L of beam b at column c, and the column's time after the stamp.
  int num_columns() const { return num_columns_; }
  Eigen::Vector3d BeamDirection(int beam, int column) const;
  double ColumnTime(int column) const;

 private:
  SimulationOptions options_;
  Scenario scenario_;
  sensors::Calibration nominal_;
  geometry::Pose3d T_V_I_, T_V_L_;
  int64_t first_sweep_stamp_ns_ = 0;
  int num_sweeps_ = 0;
  int num_columns_ = 0;
  // Unit beam directions in L, column-major: beam b of column c at c * num_beams + b.
  std::vector<Eigen::Vector3d> beam_directions_;
};

// Everything in memory (sweeps included: use for short logs).
struct SimulatedLog {
  ImuLog imu;
  sensors::WheelSamples wheel;
  GnssLog gnss;
  std::vector<lidar::LidarSweep> sweeps;
};
SimulatedLog Simulate(const Simulator& simulator);
SimulatedLog Simulate(const SimulationOptions& options);

// Figures that describe a simulated log (printed by autocal_simulate).
struct SimulationSummary {
  std::string scenario;
  double duration_s = 0.0;
  double distance_m = 0.0;
  double min_speed_m_s = 0.0, max_speed_m_s = 0.0;
  double max_yaw_rate_deg_s = 0.0;
  double total_turn_deg = 0.0;  // integral of |yaw rate|
  double max_lateral_accel_m_s2 = 0.0;
  double min_pitch_deg = 0.0, max_pitch_deg = 0.0;
  double min_roll_deg = 0.0, max_roll_deg = 0.0;
  double standstill_s = 0.0;
  int64_t imu_samples = 0, wheel_samples = 0, gnss_fixes = 0, gnss_outliers = 0;
  // GNSS outages within the log (overlapping ones merged) and the time they take from it.
  int gnss_outages = 0;
  double gnss_outage_s = 0.0;
  int64_t sweeps = 0, points = 0;
  double imu_rate_hz = 0.0, wheel_rate_hz = 0.0, gnss_rate_hz = 0.0;
  double time_offset_wheel_imu_s = 0.0, time_offset_gnss_imu_s = 0.0;  // true
  sensors::Calibration true_calibration, nominal_calibration;
};

// Figures of the drive (from the truth) and of the logs generated so far.
SimulationSummary Summarize(const Simulator& simulator, const ImuLog& imu,
                            const sensors::WheelSamples& wheel, const GnssLog& gnss, int64_t sweeps,
                            int64_t points);
std::string FormatSummary(const SimulationSummary& summary);

// Simulates and writes a dataset directory (DESIGN.md "Data formats") through
// io::DatasetWriter, sweep by sweep; adds groundtruth/imu_bias.csv and groundtruth/gnss.csv
// (true antenna position and outlier flag per fix) and groundtruth/timing.yaml (the
// sensor clock offsets and stamp models, truth an estimator of them compares with). Sweeps
// are generated on num_threads threads; the files are the same whatever the count. Throws
// autocal::Error on I/O failure or num_threads < 1.
SimulationSummary WriteDataset(const Simulator& simulator, const std::string& directory,
                               int num_threads = 1);

}  // namespace sim
}  // namespace autocal
