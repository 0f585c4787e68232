// The simulation's options: their checks, the default true calibration, a mount change and
// the noise-free copy (autocal/sim/simulator.h).

#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/units.h"
#include "autocal/io/sensors_yaml.h"
#include "autocal/sim/simulator.h"
#include "sim/simulation_options_check.h"

namespace autocal {
namespace sim {
namespace internal {
namespace {

void Require(bool ok, const std::string& what) {
  if (!ok) throw Error("simulation options: " + what);
}

// ", got <value>" for a refused value.
std::string Got(double value) { return ", got " + FormatShort(value); }

// Stamp options of a sensor at rate_hz: jitter below 0.4 periods.
void ValidateJitter(double jitter_s, double rate_hz, const std::string& sensor) {
  Require(jitter_s >= 0.0 && jitter_s < 0.4 / rate_hz,
          sensor + " stamp_jitter_s must be in [0, 0.4 / rate_hz) = [0, " +
              FormatShort(0.4 / rate_hz) + ") s at " + FormatShort(rate_hz) + " Hz" +
              Got(jitter_s) + " s");
}

// A wheel sigma as sensors.yaml states it: the dataset reader's range.
void ValidateStatedSigma(double sigma, const std::string& name, const char* unit) {
  Require(sigma >= io::kMinWheelSigma && sigma <= io::kMaxWheelSigma,
          name + " must be in [" + FormatShort(io::kMinWheelSigma) + ", " +
              FormatShort(io::kMaxWheelSigma) + "] " + unit +
              " (the sigma sensors.yaml states; for exact data simulate without noise)" +
              Got(sigma));
}

void ValidateClocks(const SimulationOptions& o) {
  ValidateJitter(o.imu.stamp_jitter_s, o.imu.noise.update_rate_hz, "imu");
  const WheelSimOptions& w = o.wheel;
  ValidateJitter(w.stamp_jitter_s, w.config.rate_hz, "wheel");
  Require(w.burst_size >= 1 && w.burst_size <= 50, "wheel burst_size must be in [1, 50]");
  Require(w.burst_span_s >= 0.0 && w.burst_span_s < 1.0 / w.config.rate_hz,
          "wheel burst_span_s must be in [0, 1 / rate_hz) = [0, " +
              FormatShort(1.0 / w.config.rate_hz) + ") s" + Got(w.burst_span_s) + " s");
  Require(w.drop_probability >= 0.0 && w.drop_probability <= 0.5,
          "wheel drop_probability must be in [0, 0.5]");
  Require(std::abs(w.time_offset_wheel_imu_s) <= 2.0,
          "|wheel time_offset_wheel_imu_s| must be at most 2 s");
  const sensors::Calibration& c = o.true_calibration;
  Require(c.wheel_speed_scale_left > 0.5 && c.wheel_speed_scale_left < 2.0 &&
              c.wheel_speed_scale_right > 0.5 && c.wheel_speed_scale_right < 2.0 &&
              c.odometry_speed_scale > 0.5 && c.odometry_speed_scale < 2.0,
          "wheel speed scales and odometry_speed_scale must be in (0.5, 2)");
  Require(c.effective_track_m > 0.1, "effective_track_m must exceed 0.1 m");
  ValidateStatedSigma(w.config.noise_rad_s, "wheel noise_rad_s", "rad/s");
  ValidateStatedSigma(w.config.noise_m_s, "wheel noise_m_s", "m/s");
  ValidateStatedSigma(w.config.yaw_rate_noise_rad_s, "wheel yaw_rate_noise_rad_s", "rad/s");
  ValidateStatedSigma(w.config.lateral_slip_sigma_m_s, "wheel lateral_slip_sigma_m_s", "m/s");
  const double compliance = w.config.cornering_compliance_rad_per_m_s2;
  Require(
      compliance >= 0.0 && compliance <= 1.0,
      "wheel cornering_compliance_rad_per_m_s2 must be in [0, 1] rad/(m/s^2)" + Got(compliance));
  Require(!w.config.controller_track_m || *w.config.controller_track_m > 0.0,
          "wheel controller_track_m must be positive");
  Require(std::abs(o.gnss.time_offset_gnss_imu_s) <= 2.0,
          "|gnss time_offset_gnss_imu_s| must be at most 2 s");
  // The sensors' clocks are simulated from the wheel and GNSS options; the truth reports them.
  Require(
      c.time_offset_wheel_imu_s == 0.0 || c.time_offset_wheel_imu_s == w.time_offset_wheel_imu_s,
      "true_calibration.time_offset_wheel_imu_s must be 0 or wheel.time_offset_wheel_imu_s "
      "(the wheel clock is simulated from the latter)");
  Require(
      c.time_offset_gnss_imu_s == 0.0 || c.time_offset_gnss_imu_s == o.gnss.time_offset_gnss_imu_s,
      "true_calibration.time_offset_gnss_imu_s must be 0 or gnss.time_offset_gnss_imu_s "
      "(the GNSS clock is simulated from the latter)");
}

}  // namespace

void ValidateSimulationOptions(const SimulationOptions& o) {
  Require(o.duration_s > 0.0 && o.duration_s <= 3600.0, "duration_s must be in (0, 3600]");
  Require(o.imu.noise.update_rate_hz >= 20.0 && o.imu.noise.update_rate_hz <= 2000.0,
          "imu update_rate_hz must be in [20, 2000]");
  // sensors.yaml states the densities times these scales, which its reader needs positive.
  Require(o.imu.noise_scale > 0.0 && std::isfinite(o.imu.noise_scale),
          "imu noise_scale must be > 0 (it scales the densities sensors.yaml states; for exact "
          "data simulate without noise)" +
              Got(o.imu.noise_scale));
  Require(o.imu.RandomWalkScale() > 0.0 && std::isfinite(o.imu.RandomWalkScale()),
          "imu random_walk_scale must be > 0" + Got(o.imu.RandomWalkScale()));
  const sensors::LidarConfig& l = o.lidar.config;
  Require(l.num_beams >= 1 && l.num_beams <= 256, "lidar num_beams must be in [1, 256]");
  Require(l.rate_hz >= 1.0 && l.rate_hz <= 50.0, "lidar rate_hz must be in [1, 50]");
  Require(l.azimuth_resolution_deg >= 0.05 && l.azimuth_resolution_deg <= 10.0,
          "lidar azimuth_resolution_deg must be in [0.05, 10]");
  Require(l.max_elevation_deg > l.min_elevation_deg && l.min_elevation_deg >= -90.0 &&
              l.max_elevation_deg <= 90.0,
          "lidar elevations must satisfy -90 <= min < max <= 90");
  Require(l.min_range_m >= 0.0 && l.max_range_m > l.min_range_m,
          "lidar ranges must satisfy 0 <= min_range_m < max_range_m, got " +
              FormatShort(l.min_range_m) + " and " + FormatShort(l.max_range_m) + " m");
  Require(l.range_noise_m >= 0.0, "lidar range_noise_m must be >= 0");
  Require(o.lidar.dropout_probability >= 0.0 && o.lidar.dropout_probability < 1.0,
          "lidar dropout_probability must be in [0, 1)");
  Require(o.wheel.config.rate_hz > 0.0 && o.wheel.config.rate_hz <= 1000.0,
          "wheel rate_hz must be in (0, 1000]");
  Require(o.gnss.config.rate_hz > 0.0 && o.gnss.config.rate_hz <= 100.0,
          "gnss rate_hz must be in (0, 100]");
  ValidateClocks(o);
  Require((o.gnss.std_enu_m.array() > 0.0).all(), "gnss std_enu_m must be positive");
  Require(o.gnss.error_correlation_time_s >= 0.0 && std::isfinite(o.gnss.error_correlation_time_s),
          "gnss error_correlation_time_s must be finite and >= 0");
  Require(o.gnss.outlier_probability >= 0.0 && o.gnss.outlier_probability <= 1.0,
          "gnss outlier_probability must be in [0, 1]");
  Require(o.gnss.num_outages >= 0,
          "gnss num_outages must be >= 0" + Got(static_cast<double>(o.gnss.num_outages)));
  Require(o.gnss.outage_duration_s >= 0.0 && std::isfinite(o.gnss.outage_duration_s),
          "gnss outage_duration_s must be finite and >= 0" + Got(o.gnss.outage_duration_s) + " s");
  Require(std::abs(o.gnss.origin_lat_deg) < 85.0 && std::abs(o.gnss.origin_lon_deg) <= 180.0,
          "gnss origin latitude/longitude out of range");
  // From below the Dead Sea's shore (-430 m) to above any road or aircraft a dataset records.
  Require(o.gnss.origin_alt_m >= -1000.0 && o.gnss.origin_alt_m <= 100000.0,
          "gnss origin_alt_m must be in [-1000, 100000] m" + Got(o.gnss.origin_alt_m));
  Require(std::abs(o.true_calibration.time_offset_lidar_imu_s) < 0.5,
          "|time_offset_lidar_imu_s| must be below 0.5 s");
  Require(o.true_calibration.wheel_radius_left_m > 0.05 &&
              o.true_calibration.wheel_radius_right_m > 0.05 &&
              o.true_calibration.track_width_m > 0.3,
          "wheel radii must exceed 0.05 m and the track width 0.3 m");
  const NominalPerturbation& np = o.nominal_perturbation;
  Require(np.rotation_deg >= 0.0 && np.translation_m >= 0.0 && np.time_offset_s >= 0.0,
          "nominal_perturbation sigmas must be >= 0");
  Require(!np.state_uncertainty ||
              (np.rotation_deg > 0.0 && np.translation_m > 0.0 && np.time_offset_s > 0.0 &&
               np.wheel_radius_sigma_m > 0.0 && np.track_width_sigma_m > 0.0),
          "nominal_perturbation: a stated uncertainty needs every sigma > 0 "
          "(or state_uncertainty = false)");
  Require(!np.q_I_V || (std::abs(np.q_I_V->norm() - 1.0) < 1e-6 && np.q_I_V_sigma_deg > 0.0),
          "nominal_perturbation q_I_V must be a unit quaternion with q_I_V_sigma_deg > 0");
}

}  // namespace internal

Eigen::Quaterniond RotationFromRollPitchYawDeg(double roll_deg, double pitch_deg, double yaw_deg) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw_deg * kDegToRad, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(pitch_deg * kDegToRad, Eigen::Vector3d::UnitY()) *
                            Eigen::AngleAxisd(roll_deg * kDegToRad, Eigen::Vector3d::UnitX()));
}

sensors::Calibration WithImuMount(const sensors::Calibration& calibration,
                                  const Eigen::Quaterniond& q_V_I) {
  const geometry::Pose3d T_V_I_old =
      geometry::Pose3d(calibration.q_I_V, calibration.p_I_V).Inverse();
  const geometry::Pose3d T_V_I(q_V_I.normalized(), T_V_I_old.p);
  const geometry::Pose3d T_I_V = T_V_I.Inverse();
  // New IMU frame from the old one: T_Inew_Iold = T_Inew_V T_V_Iold.
  const geometry::Pose3d T_new_old = T_I_V * T_V_I_old;
  sensors::Calibration c = calibration;
  c.q_I_V = T_I_V.q;
  c.p_I_V = T_I_V.p;
  const geometry::Pose3d T_I_L = T_new_old * geometry::Pose3d(calibration.q_I_L, calibration.p_I_L);
  c.q_I_L = T_I_L.q;
  c.p_I_L = T_I_L.p;
  c.p_I_A = T_new_old * calibration.p_I_A;
  return c;
}

sensors::Calibration DefaultTrueCalibration() {
  sensors::Calibration c;
  const geometry::Pose3d T_V_I(RotationFromRollPitchYawDeg(0.3, -0.5, 1.0),
                               Eigen::Vector3d(1.3, 0.0, 1.2));
  const geometry::Pose3d T_I_V = T_V_I.Inverse();
  c.q_I_V = T_I_V.q;
  c.p_I_V = T_I_V.p;
  c.q_I_L = RotationFromRollPitchYawDeg(2.0, -3.0, 4.0);
  c.p_I_L = Eigen::Vector3d(0.30, -0.05, 0.55);
  c.time_offset_lidar_imu_s = 0.025;
  c.wheel_radius_left_m = 0.3335;
  c.wheel_radius_right_m = 0.3326;
  c.track_width_m = 1.62;
  c.p_I_A = Eigen::Vector3d(-1.2, 0.05, 0.65);
  return c;
}

SimulationOptions SimulationOptions::WithoutNoise() const {
  SimulationOptions o = *this;
  o.imu.add_noise = false;
  o.lidar.add_noise = false;
  o.lidar.dropout_probability = 0.0;
  o.wheel.add_noise = false;
  o.gnss.add_noise = false;
  o.gnss.outlier_probability = 0.0;
  return o;
}

}  // namespace sim
}  // namespace autocal
