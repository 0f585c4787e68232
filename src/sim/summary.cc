#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <utility>

#include "autocal/common/units.h"
#include "autocal/sim/simulator.h"

namespace autocal {
namespace sim {
namespace {

std::string Format(const char* format, double a) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), format, a);
  return buffer;
}

// Roll, pitch, yaw (deg) of R = Rz(yaw) Ry(pitch) Rx(roll).
Eigen::Vector3d RollPitchYawDeg(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d R = q.toRotationMatrix();
  return kRadToDeg * Eigen::Vector3d(std::atan2(R(2, 1), R(2, 2)), -std::asin(R(2, 0)),
                                     std::atan2(R(1, 0), R(0, 0)));
}

std::string Pad(const char* name) {
  std::string s = name;
  s.resize(std::max<size_t>(s.size(), 16), ' ');
  return s;
}

std::string Vec(const Eigen::Vector3d& v, const char* format) {
  return "(" + Format(format, v.x()) + ", " + Format(format, v.y()) + ", " + Format(format, v.z()) +
         ")";
}

}  // namespace

SimulationSummary Summarize(const Simulator& simulator, const ImuLog& imu,
                            const sensors::WheelSamples& wheel, const GnssLog& gnss, int64_t sweeps,
                            int64_t points) {
  SimulationSummary s;
  const SimulationOptions& options = simulator.options();
  const VehicleTrajectory& trajectory = *simulator.scenario().trajectory;
  s.scenario = ScenarioName(options.scenario);
  s.duration_s = options.duration_s;
  // The drive's figures from the truth of the V frame, at 50 Hz.
  constexpr double kStep = 0.02;
  s.min_speed_m_s = 1e9;
  s.min_pitch_deg = s.min_roll_deg = 1e9;
  s.max_pitch_deg = s.max_roll_deg = -1e9;
  for (double t = 0.0; t <= options.duration_s; t += kStep) {
    const BodyState state = trajectory.StateAt(t);
    const double speed = state.v_W.norm();
    const double yaw_rate = state.omega_B.z() * kRadToDeg;
    const Eigen::Vector3d a_V = state.T_W_B.q.conjugate() * state.a_W;
    const Eigen::Vector3d rpy = RollPitchYawDeg(state.T_W_B.q);
    s.distance_m += speed * kStep;
    s.min_speed_m_s = std::min(s.min_speed_m_s, speed);
    s.max_speed_m_s = std::max(s.max_speed_m_s, speed);
    s.max_yaw_rate_deg_s = std::max(s.max_yaw_rate_deg_s, std::abs(yaw_rate));
    s.total_turn_deg += std::abs(yaw_rate) * kStep;
    s.max_lateral_accel_m_s2 = std::max(s.max_lateral_accel_m_s2, std::abs(a_V.y()));
    // Nose up is positive pitch here (the opposite sign of the rotation about y_V).
    s.min_pitch_deg = std::min(s.min_pitch_deg, -rpy.y());
    s.max_pitch_deg = std::max(s.max_pitch_deg, -rpy.y());
    s.min_roll_deg = std::min(s.min_roll_deg, rpy.x());
    s.max_roll_deg = std::max(s.max_roll_deg, rpy.x());
    if (speed < 0.01) s.standstill_s += kStep;
  }
  s.imu_samples = static_cast<int64_t>(imu.samples.size());
  s.wheel_samples = static_cast<int64_t>(wheel.size());
  s.gnss_fixes = static_cast<int64_t>(gnss.fixes.size());
  s.gnss_outliers = std::count(gnss.is_outlier.begin(), gnss.is_outlier.end(), true);
  // The outages as the log has them: overlapping ones merged, the parts past its end left out.
  double covered_until = 0.0;
  for (const auto& [begin, end] : gnss.outages_s) {  // sorted by their begin
    const double from = std::max(begin, covered_until), to = std::min(end, options.duration_s);
    if (to <= from) continue;
    if (from > covered_until || s.gnss_outages == 0) ++s.gnss_outages;
    s.gnss_outage_s += to - from;
    covered_until = to;
  }
  s.sweeps = sweeps;
  s.points = points;
  s.imu_rate_hz = options.imu.noise.update_rate_hz;
  s.wheel_rate_hz = options.wheel.config.rate_hz;
  s.gnss_rate_hz = options.gnss.config.rate_hz;
  s.time_offset_wheel_imu_s = options.wheel.time_offset_wheel_imu_s;
  s.time_offset_gnss_imu_s = options.gnss.time_offset_gnss_imu_s;
  s.true_calibration = simulator.true_calibration();
  s.nominal_calibration = simulator.nominal_calibration();
  return s;
}

std::string FormatSummary(const SimulationSummary& s) {
  std::ostringstream out;
  out << "scenario        " << s.scenario << ", " << Format("%.1f", s.duration_s) << " s, "
      << Format("%.0f", s.distance_m) << " m driven\n";
  out << "speed           " << Format("%.1f", s.min_speed_m_s * 3.6) << " .. "
      << Format("%.1f", s.max_speed_m_s * 3.6) << " km/h, standing "
      << Format("%.1f", s.standstill_s) << " s\n";
  out << "turning         max yaw rate " << Format("%.1f", s.max_yaw_rate_deg_s)
      << " deg/s, total turned " << Format("%.0f", s.total_turn_deg) << " deg, max lateral accel "
      << Format("%.2f", s.max_lateral_accel_m_s2) << " m/s^2\n";
  out << "attitude        pitch " << Format("%.2f", s.min_pitch_deg) << " .. "
      << Format("%.2f", s.max_pitch_deg) << " deg, roll " << Format("%.2f", s.min_roll_deg)
      << " .. " << Format("%.2f", s.max_roll_deg) << " deg\n";
  out << "imu             " << s.imu_samples << " samples (" << Format("%g", s.imu_rate_hz)
      << " Hz)\n";
  out << "wheel           " << s.wheel_samples << " samples (" << Format("%g", s.wheel_rate_hz)
      << " Hz), clock offset " << Format("%.1f", s.time_offset_wheel_imu_s * 1e3) << " ms\n";
  out << "gnss            " << s.gnss_fixes << " fixes (" << Format("%g", s.gnss_rate_hz)
      << " Hz), " << s.gnss_outliers << " outliers, " << s.gnss_outages << " outages ("
      << Format("%.1f", s.gnss_outage_s) << " s), clock offset "
      << Format("%.1f", s.time_offset_gnss_imu_s * 1e3) << " ms\n";
  out << "lidar           " << s.sweeps << " sweeps, " << s.points << " points ("
      << (s.sweeps > 0 ? s.points / s.sweeps : 0) << " per sweep)\n";

  const sensors::Calibration& t = s.true_calibration;
  const sensors::Calibration& n = s.nominal_calibration;
  auto rotation_row = [&](const char* name, const Eigen::Quaterniond& qt,
                          const Eigen::Quaterniond& qn) {
    out << Pad(name) << "true rpy " << Vec(RollPitchYawDeg(qt), "%.2f") << " deg, nominal "
        << Vec(RollPitchYawDeg(qn), "%.2f") << " deg, off by "
        << Format("%.2f", geometry::AngularDistance(qt, qn) * kRadToDeg) << " deg\n";
  };
  auto translation_row = [&](const char* name, const Eigen::Vector3d& pt,
                             const Eigen::Vector3d& pn) {
    out << Pad(name) << "true " << Vec(pt, "%.3f") << " m, nominal " << Vec(pn, "%.3f")
        << " m, off by " << Format("%.1f", (pt - pn).norm() * 100.0) << " cm\n";
  };
  auto scalar_row = [&](const char* name, double vt, double vn, const char* unit, double scale) {
    out << Pad(name) << "true " << Format("%.4f", vt * scale) << " " << unit << ", nominal "
        << Format("%.4f", vn * scale) << " " << unit << "\n";
  };
  out << "calibration (true vs nominal in sensors.yaml)\n";
  rotation_row("  q_I_L", t.q_I_L, n.q_I_L);
  translation_row("  p_I_L", t.p_I_L, n.p_I_L);
  scalar_row("  time offset", t.time_offset_lidar_imu_s, n.time_offset_lidar_imu_s, "ms", 1e3);
  rotation_row("  q_I_V", t.q_I_V, n.q_I_V);
  translation_row("  p_I_V", t.p_I_V, n.p_I_V);
  translation_row("  p_I_A", t.p_I_A, n.p_I_A);
  scalar_row("  radius left", t.wheel_radius_left_m, n.wheel_radius_left_m, "m", 1.0);
  scalar_row("  radius right", t.wheel_radius_right_m, n.wheel_radius_right_m, "m", 1.0);
  scalar_row("  track width", t.track_width_m, n.track_width_m, "m", 1.0);
  // The other wheel forms' blocks where the truth differs from the nominal value.
  const std::pair<const char*, double sensors::Calibration::*> form_blocks[] = {
      {"  scale left", &sensors::Calibration::wheel_speed_scale_left},
      {"  scale right", &sensors::Calibration::wheel_speed_scale_right},
      {"  odometry k_v", &sensors::Calibration::odometry_speed_scale},
      {"  eff. track", &sensors::Calibration::effective_track_m}};
  for (const auto& [name, member] : form_blocks) {
    if (t.*member == n.*member) continue;
    const char* unit = member == &sensors::Calibration::effective_track_m ? " m" : "";
    out << Pad(name) << "true " << Format("%.4f", t.*member) << unit << ", nominal "
        << Format("%.4f", n.*member) << unit << "\n";
  }
  return out.str();
}

}  // namespace sim
}  // namespace autocal
