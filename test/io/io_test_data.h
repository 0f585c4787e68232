#pragma once

// A small dataset generated from a known analytic motion, for the io round-trip and
// bad-input tests: the IMU (aligned with the vehicle frame) drives a circle of radius
// kRadius at yaw rate kYawRate while bobbing vertically, so every quantity has a closed
// form: p_W_I(t) = (R sin(wt), R (1 - cos(wt)), A sin(Wt)), yaw(t) = wt.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/io/dataset.h"

namespace autocal {
namespace io {
namespace test_data {

constexpr double kRadius = 20.0;        // m
constexpr double kYawRate = 0.25;       // rad/s (v = 5 m/s)
constexpr double kBobAmplitude = 0.05;  // m
constexpr double kBobRate = 3.0;        // rad/s
constexpr double kGravity = 9.80665;
constexpr int64_t kStartNs = 1'700'000'000'123'456'789;

inline TrajectorySample StateAt(double t) {
  const double yaw = kYawRate * t;
  TrajectorySample s;
  s.T_W_I.p << kRadius * std::sin(yaw), kRadius * (1.0 - std::cos(yaw)),
      kBobAmplitude * std::sin(kBobRate * t);
  s.T_W_I.q = Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
  s.v_W_I << kRadius * kYawRate * std::cos(yaw), kRadius * kYawRate * std::sin(yaw),
      kBobAmplitude * kBobRate * std::cos(kBobRate * t);
  return s;
}

// Specific force and rate in I: f = R_W_I^T (a_W - g_W), omega = (0, 0, w).
inline sensors::ImuSample ImuAt(int64_t t_ns) {
  const double t = SecondsBetween(kStartNs, t_ns);
  const double yaw = kYawRate * t;
  const Eigen::Vector3d a_W(-kRadius * kYawRate * kYawRate * std::sin(yaw),
                            kRadius * kYawRate * kYawRate * std::cos(yaw),
                            -kBobAmplitude * kBobRate * kBobRate * std::sin(kBobRate * t));
  const Eigen::Vector3d g_W(0.0, 0.0, -kGravity);
  sensors::ImuSample sample;
  sample.t_ns = t_ns;
  sample.gyro_rad_s << 0.0, 0.0, kYawRate;
  sample.accel_m_s2 = StateAt(t).T_W_I.q.conjugate() * (a_W - g_W);
  return sample;
}

inline sensors::Calibration TrueCalibration() {
  sensors::Calibration c;
  c.q_I_L = Eigen::Quaterniond(Eigen::AngleAxisd(0.02, Eigen::Vector3d(1, -2, 3).normalized()));
  c.p_I_L << 0.8, -0.05, 1.3;
  c.time_offset_lidar_imu_s = 0.0123;
  c.q_I_V = Eigen::Quaterniond(Eigen::AngleAxisd(-0.01, Eigen::Vector3d::UnitY()));
  c.p_I_V << -1.2, 0.01, -0.3;
  c.wheel_radius_left_m = 0.331;
  c.wheel_radius_right_m = 0.329;
  c.track_width_m = 1.58;
  c.p_I_A << -0.4, 0.2, 1.1;
  return c;
}

struct Drive {
  SensorsConfig config;
  sensors::ImuSamples imu;
  sensors::WheelSamples wheel;
  sensors::GnssFixes gnss;
  std::vector<lidar::LidarSweep> sweeps;
  Trajectory trajectory;
  sensors::Calibration calibration;
};

// `duration_s` of driving: IMU 200 Hz, wheels 100 Hz, GNSS 10 Hz, LiDAR 10 Hz (small
// sweeps: a ring of points around the car), ground truth at 100 Hz.
inline Drive MakeDrive(double duration_s) {
  Drive d;
  d.calibration = TrueCalibration();
  d.config.lidar = sensors::LidarConfig();
  d.config.wheel = sensors::WheelConfig();
  d.config.gnss = sensors::GnssConfig();
  d.config.nominal_calibration = d.calibration;
  d.config.nominal_calibration.p_I_L += Eigen::Vector3d(0.05, 0.0, -0.02);
  const int64_t duration_ns = SecondsToNs(duration_s);
  for (int64_t dt = 0; dt <= duration_ns; dt += 5'000'000) d.imu.push_back(ImuAt(kStartNs + dt));
  const double v = kRadius * kYawRate;
  const double half_track = 0.5 * d.calibration.track_width_m;
  for (int64_t dt = 0; dt <= duration_ns; dt += 10'000'000) {
    sensors::WheelSample w;
    w.t_ns = kStartNs + dt;
    w.left_rad_s = (v - kYawRate * half_track) / d.calibration.wheel_radius_left_m;
    w.right_rad_s = (v + kYawRate * half_track) / d.calibration.wheel_radius_right_m;
    d.wheel.push_back(w);
    TrajectorySample s = StateAt(NsToSeconds(dt));
    s.t_ns = kStartNs + dt;
    d.trajectory.push_back(s);
  }
  constexpr double kEarthRadius = 6378137.0;
  for (int64_t dt = 0; dt <= duration_ns; dt += 100'000'000) {
    const TrajectorySample s = StateAt(NsToSeconds(dt));
    const Eigen::Vector3d p_W_A = s.T_W_I * d.calibration.p_I_A;
    sensors::GnssFix fix;
    fix.t_ns = kStartNs + dt;
    fix.lat_deg = 48.137 + p_W_A.y() / kEarthRadius * kRadToDeg;
    fix.lon_deg = 11.575 + p_W_A.x() / (kEarthRadius * std::cos(48.137 * kDegToRad)) * kRadToDeg;
    fix.alt_m = 519.0 + p_W_A.z();
    fix.std_enu_m << 0.02, 0.02, 0.05;
    d.gnss.push_back(fix);
    lidar::LidarSweep sweep;
    sweep.t_ns = kStartNs + dt;
    const int n = 90;
    sweep.cloud.points.resize(3, n);
    sweep.cloud.intensity.resize(n);
    sweep.cloud.time_s.resize(n);
    for (int i = 0; i < n; ++i) {
      // Points on a 1/256 m grid and times on a 1/4096 s grid: exact in float.
      const double angle = 2.0 * M_PI * i / n;
      sweep.cloud.points.col(i) << std::round(256.0 * 10.0 * std::cos(angle)) / 256.0,
          std::round(256.0 * 10.0 * std::sin(angle)) / 256.0, -1.5 + (i % 8) / 8.0;
      sweep.cloud.intensity[i] = static_cast<float>((i * 37) % 255);
      sweep.cloud.time_s[i] = std::round(4096.0 * 0.1 * i / n) / 4096.0;
    }
    d.sweeps.push_back(sweep);
  }
  return d;
}

}  // namespace test_data
}  // namespace io
}  // namespace autocal
