// Simulation options after two real platforms (simulator.h, docs/simulator.md "Presets").

#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/sim/simulator.h"

namespace autocal {
namespace sim {
namespace {

// A small mounting error on top of a nominal mount, so that the truth is not the round value
// a launch file states.
Eigen::Quaterniond MountWithError(const Eigen::Quaterniond& q_V_I_nominal) {
  return (q_V_I_nominal * RotationFromRollPitchYawDeg(0.6, -0.5, 0.7)).normalized();
}

}  // namespace

void SetSpinningLidarBeams(int num_beams, sensors::LidarConfig* config) {
  switch (num_beams) {
    case 16:
      config->min_elevation_deg = -15.0;
      config->max_elevation_deg = 15.0;
      break;
    case 32:
      config->min_elevation_deg = -25.0;
      config->max_elevation_deg = 15.0;
      break;
    case 64:
      config->min_elevation_deg = -24.8;
      config->max_elevation_deg = 2.0;
      break;
    default:
      throw Error("a spinning LiDAR has 16, 32 or 64 beams here, got " + std::to_string(num_beams));
  }
  config->num_beams = num_beams;
}

sensors::WheelConfig RoadCarWheelConfig() {
  sensors::WheelConfig config;
  config.cornering_compliance_rad_per_m_s2 = 0.3 * kDegToRad;
  config.lateral_slip_sigma_m_s = 0.01;
  return config;
}

void StateSkidSteerSlip(sensors::WheelConfig* config) {
  const sensors::WheelConfig defaults;
  config->lateral_slip_sigma_m_s = defaults.lateral_slip_sigma_m_s;
  config->cornering_compliance_rad_per_m_s2 = defaults.cornering_compliance_rad_per_m_s2;
}

SimulationOptions SkidSteerRobotOptions() {
  SimulationOptions o;
  o.scenario = ScenarioType::kSkidSteer;
  o.duration_s = 300.0;
  // A stiff body on small wheels; V's origin is the centre between the four wheels (the
  // pivot centre), 0.17 m above the ground.
  o.dynamics.roll_per_lateral_accel = 0.1 * kDegToRad;
  o.dynamics.pitch_per_longitudinal_accel = 0.1 * kDegToRad;
  o.dynamics.rear_axle_height_m = 0.17;
  o.imu.noise.update_rate_hz = 30.0;
  o.imu.stamp_jitter_s = 0.002;
  StateSkidSteerSlip(&o.wheel.config);

  sensors::Calibration c = DefaultTrueCalibration();
  // IMU y up, x right (R_V_I = Rz(-90) Rx(+90)), 0.3 m above V's origin; LiDAR 0.5 m up.
  const Eigen::Quaterniond q_V_I_nominal = RotationFromRollPitchYawDeg(90.0, 0.0, -90.0);
  const geometry::Pose3d T_V_I(MountWithError(q_V_I_nominal), Eigen::Vector3d(0.05, 0.0, 0.30));
  const geometry::Pose3d T_V_L(RotationFromRollPitchYawDeg(0.5, -1.0, 2.0),
                               Eigen::Vector3d(0.20, 0.0, 0.50));
  const geometry::Pose3d T_I_V = T_V_I.Inverse();
  const geometry::Pose3d T_I_L = T_I_V * T_V_L;
  c.q_I_V = T_I_V.q;
  c.p_I_V = T_I_V.p;
  c.q_I_L = T_I_L.q;
  c.p_I_L = T_I_L.p;
  c.time_offset_lidar_imu_s = 0.0;
  c.p_I_A = T_I_V * Eigen::Vector3d(-0.25, 0.0, 0.65);
  c.wheel_radius_left_m = 0.1655;
  c.wheel_radius_right_m = 0.1648;
  // Skid steer: the wheels slip sideways in a turn, so the yaw rate is (v_r - v_l) / b_eff
  // with an effective track 1.875 times the physical 0.555 m.
  c.track_width_m = 1.875 * 0.555;
  // As odometry twist (config.form speed_yaw_rate): the controller divides by the physical
  // track and its radius is 3 % large, so it reports 3 % too much speed.
  c.effective_track_m = c.track_width_m;
  c.odometry_speed_scale = 0.97;
  o.true_calibration = c;
  o.nominal_wheel_radius_m = 0.165;
  o.nominal_track_width_m = 0.555;
  o.nominal_perturbation.wheel_radius_sigma_m = 0.003;
  o.nominal_perturbation.track_width_sigma_m = 0.6;
  o.nominal_perturbation.q_I_V = q_V_I_nominal.conjugate();
  o.nominal_perturbation.q_I_V_sigma_deg = 5.0;

  o.lidar.enabled = false;
  o.wheel.config.rate_hz = 10.0;
  o.wheel.config.noise_rad_s = 0.05;
  o.wheel.config.noise_m_s = 0.01;
  o.wheel.config.yaw_rate_noise_rad_s = 0.02;
  o.wheel.stamp_jitter_s = 0.01;
  o.wheel.drop_probability = 0.02;
  o.wheel.time_offset_wheel_imu_s = -0.38;  // odometry stamped 0.38 s after the motion
  o.gnss.config.rate_hz = 2.5;
  o.gnss.std_enu_m = Eigen::Vector3d(0.6, 0.6, 1.2);
  o.gnss.num_outages = 0;
  o.gnss.outlier_probability = 0.0;
  return o;
}

SimulationOptions CanBusCarOptions() {
  SimulationOptions o;
  o.scenario = ScenarioType::kStraight;
  o.duration_s = 60.0;
  o.imu.noise.update_rate_hz = 104.0;
  o.imu.stamp_jitter_s = 0.0005;
  o.imu.noise_scale = 3.0;  // phone-grade
  // x forward, y right, z down: R_V_I = Rx(180 deg), the other sensors kept in V.
  const Eigen::Quaterniond q_V_I_nominal = RotationFromRollPitchYawDeg(180.0, 0.0, 0.0);
  o.true_calibration = WithImuMount(DefaultTrueCalibration(), MountWithError(q_V_I_nominal));
  o.nominal_perturbation.q_I_V = q_V_I_nominal.conjugate();
  o.nominal_perturbation.q_I_V_sigma_deg = 5.0;
  o.lidar.enabled = false;
  o.wheel.config.rate_hz = 83.0;
  o.wheel.burst_size = 4;
  o.wheel.burst_span_s = 0.002;
  o.gnss.config.rate_hz = 10.0;
  o.gnss.time_offset_gnss_imu_s = -0.2;  // stamped 0.2 s after the fix
  o.gnss.std_enu_m = Eigen::Vector3d(0.5, 0.5, 1.0);
  return o;
}

}  // namespace sim
}  // namespace autocal
