#include "autocal/io/calibration_export.h"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cctype>
#include <cmath>
#include <sstream>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/geometry/roll_pitch_yaw.h"
#include "autocal/geometry/se3.h"
#include "text_format.h"

namespace autocal {
namespace io {
namespace {

// Shortest round-trip text, without the sign of a zero ("-0" reads as a typo in a config).
std::string FormatDouble(double value) {
  return internal::FormatDouble(value == 0.0 ? 0.0 : value);
}

// A child frame in its parent: p_parent = T * p_child.
struct Transform {
  std::string parent;
  std::string child;
  geometry::Pose3d T;
};

bool HasLidar(const CalibrationFile& r) { return r.uncertainty.T_I_L.sigma_rot_deg.has_value(); }
bool HasVehicle(const CalibrationFile& r) { return r.uncertainty.T_I_V.sigma_rot_deg.has_value(); }
bool HasAntenna(const CalibrationFile& r) { return r.uncertainty.p_I_A_m.sigma.has_value(); }

// Frame names go into XML attributes and shell commands: letters, digits and _ / . - only.
void CheckFrameName(const std::string& name) {
  bool ok = !name.empty();
  for (const char c : name) {
    ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '/' || c == '.' ||
                c == '-');
  }
  if (!ok) {
    throw Error("export: frame name '" + name +
                "' must be non-empty and hold only letters, digits, '_', '/', '.' and '-'");
  }
}

// The result's frames as a tree: with the vehicle, each sensor in the vehicle frame (its
// origin below_axle_m under the rear-axle centre); without, the LiDAR and the antenna in the
// IMU frame.
std::vector<Transform> Tree(const CalibrationFile& r, const ExportOptions& o, double below_axle_m) {
  const sensors::Calibration& c = r.value;
  std::vector<Transform> out;
  geometry::Pose3d T_P_I;  // the IMU in the root P
  std::string root = o.imu_frame;
  if (HasVehicle(r)) {
    root = o.vehicle_frame;
    const geometry::Pose3d raise(Eigen::Quaterniond::Identity(),
                                 Eigen::Vector3d(0.0, 0.0, below_axle_m));
    T_P_I = raise * geometry::Pose3d(c.q_I_V, c.p_I_V).Inverse();
    out.push_back({root, o.imu_frame, T_P_I});
  }
  if (HasLidar(r)) {
    out.push_back({root, o.lidar_frame, T_P_I * geometry::Pose3d(c.q_I_L, c.p_I_L)});
  }
  if (HasAntenna(r)) {
    out.push_back(
        {root, o.gnss_frame, geometry::Pose3d(Eigen::Quaterniond::Identity(), T_P_I * c.p_I_A)});
  }
  return out;
}

std::string Vector(const Eigen::Vector3d& v, const char* separator) {
  return FormatDouble(v.x()) + separator + FormatDouble(v.y()) + separator + FormatDouble(v.z());
}

Eigen::Vector3d Rpy(const Eigen::Quaterniond& q) { return geometry::RollPitchYaw(q); }

// "t_imu = t_<sensor> + 0.025 s" (or "- 0.4 s") after `prefix`, for an estimated clock.
std::string Clock(const std::string& prefix, const char* sensor, const ScalarBlockInfo& info,
                  double offset_s) {
  if (!info.sigma) return "";
  return prefix + "t_imu = t_" + sensor + (offset_s < 0.0 ? " - " : " + ") +
         FormatDouble(std::abs(offset_s)) + " s\n";
}

// The estimated clocks as comment lines starting with `prefix`.
std::string Clocks(const CalibrationFile& r, const std::string& prefix) {
  const CalibrationUncertainty& u = r.uncertainty;
  const sensors::Calibration& c = r.value;
  return Clock(prefix, "lidar", u.time_offset_lidar_imu_s, c.time_offset_lidar_imu_s) +
         Clock(prefix, "wheel", u.time_offset_wheel_imu_s, c.time_offset_wheel_imu_s) +
         Clock(prefix, "gnss", u.time_offset_gnss_imu_s, c.time_offset_gnss_imu_s);
}

void RequireLidar(const CalibrationFile& r, const char* format) {
  if (!HasLidar(r)) {
    throw Error(std::string("export ") + format +
                ": the result holds no LiDAR-IMU extrinsic (T_I_L was not estimated)");
  }
}

std::string Kalibr(const CalibrationFile& r) {
  RequireLidar(r, "kalibr");
  const geometry::Pose3d T_L_I = geometry::Pose3d(r.value.q_I_L, r.value.p_I_L).Inverse();
  const Eigen::Matrix3d R = T_L_I.R();
  const Eigen::Vector3d& t = T_L_I.p;
  std::ostringstream out;
  out << "# autocal calibration, Kalibr camchain style. T_lidar_imu takes IMU coordinates to\n"
         "# LiDAR coordinates (p_L = T_lidar_imu p_I); t_imu = t_lidar + timeshift_lidar_imu.\n"
         "lidar0:\n  T_lidar_imu:\n";
  for (int i = 0; i < 3; ++i) {
    out << "  - [" << Vector(R.row(i).transpose(), ", ") << ", " << FormatDouble(t(i)) << "]\n";
  }
  out << "  - [0.0, 0.0, 0.0, 1.0]\n"
      << "  timeshift_lidar_imu: " << FormatDouble(r.value.time_offset_lidar_imu_s) << "\n";
  return out.str();
}

// LIO-SAM rotates every IMU sample into the LiDAR frame with extrinsicRot (R_L_I), and its
// IMU pose is the LiDAR pose composed with (identity, extrinsicTrans): the IMU's origin in the
// LiDAR frame, p_L_I. Together T_L_I, which its parameter file calls "lidar -> IMU".
std::string LioSam(const CalibrationFile& r) {
  RequireLidar(r, "lio_sam");
  const geometry::Pose3d T_L_I = geometry::Pose3d(r.value.q_I_L, r.value.p_I_L).Inverse();
  const Eigen::Matrix3d R = T_L_I.R();
  const Eigen::Vector3d& p_L_I = T_L_I.p;
  const std::string rows = Vector(R.row(0).transpose(), ", ") + ",\n" + "               " +
                           Vector(R.row(1).transpose(), ", ") + ",\n" + "               " +
                           Vector(R.row(2).transpose(), ", ") + "]\n";
  std::ostringstream out;
  out << "# autocal calibration for LIO-SAM (merge into its params.yaml). extrinsicRot turns IMU\n"
         "# vectors into the LiDAR frame (R_L_I); extrinsicTrans is the IMU's origin in the\n"
         "# LiDAR frame (p_L_I). extrinsicRPY equals extrinsicRot for an IMU whose orientation\n"
         "# field is its own frame's attitude (sensor_msgs/Imu); check yours. LIO-SAM has no\n"
         "# time offset: "
      << Clock("", "lidar", r.uncertainty.time_offset_lidar_imu_s, r.value.time_offset_lidar_imu_s)
      << (r.uncertainty.time_offset_lidar_imu_s.sigma ? "" : "(not estimated)\n")
      << "extrinsicTrans: [" << Vector(p_L_I, ", ") << "]\n"
      << "extrinsicRot: [" << rows << "extrinsicRPY: [" << rows;
  return out.str();
}

std::string FastLio(const CalibrationFile& r) {
  RequireLidar(r, "fast_lio");
  const Eigen::Matrix3d R = r.value.q_I_L.normalized().toRotationMatrix();
  std::ostringstream out;
  out << "# autocal calibration for FAST-LIO (merge into its config). extrinsic_T and\n"
         "# extrinsic_R (row-major) are the LiDAR in the IMU frame: p_I = R p_L + T.\n"
         "# FAST-LIO reads time_offset_lidar_to_imu into time_diff_lidar_to_imu and subtracts it\n"
         "# from the IMU stamps: t_imu = t_lidar + offset.\n"
         "common:\n"
      << "    time_offset_lidar_to_imu: " << FormatDouble(r.value.time_offset_lidar_imu_s) << "\n"
      << "mapping:\n    extrinsic_est_en: false\n"
      << "    extrinsic_T: [" << Vector(r.value.p_I_L, ", ") << "]\n"
      << "    extrinsic_R: [" << Vector(R.row(0).transpose(), ", ") << ",\n"
      << "                  " << Vector(R.row(1).transpose(), ", ") << ",\n"
      << "                  " << Vector(R.row(2).transpose(), ", ") << "]\n";
  return out.str();
}

std::string Autoware(const CalibrationFile& r, const ExportOptions& o, double below_axle_m,
                     bool below_from_radius) {
  if (!HasVehicle(r)) {
    throw Error(
        "export autoware: the result holds no IMU mount in the vehicle (T_I_V was not "
        "estimated), so no sensor can be placed in base_link");
  }
  std::ostringstream out;
  out << "# autocal calibration, Autoware sensor kit style: each sensor frame in "
      << o.vehicle_frame << "\n# (x, y, z in m; roll, pitch, yaw in rad, R = Rz(yaw) Ry(pitch) "
      << "Rx(roll)).\n# " << o.vehicle_frame << " lies " << FormatDouble(below_axle_m)
      << " m below the rear-axle centre\n"
      << (below_from_radius ? "# (the mean calibrated rear wheel radius).\n"
                            : "# (no wheel radius was estimated: give it if the frame is on the "
                              "ground).\n")
      << Clocks(r, "# ") << o.vehicle_frame << ":\n";
  for (const Transform& t : Tree(r, o, below_axle_m)) {
    const Eigen::Vector3d rpy = Rpy(t.T.q);
    out << "  " << t.child << ":\n"
        << "    x: " << FormatDouble(t.T.p.x()) << "\n    y: " << FormatDouble(t.T.p.y())
        << "\n    z: " << FormatDouble(t.T.p.z()) << "\n    roll: " << FormatDouble(rpy(0))
        << "\n    pitch: " << FormatDouble(rpy(1)) << "\n    yaw: " << FormatDouble(rpy(2)) << "\n";
  }
  return out.str();
}

std::string Urdf(const CalibrationFile& r, const ExportOptions& o, double below_axle_m) {
  const std::vector<Transform> tree = Tree(r, o, below_axle_m);
  std::ostringstream out;
  out << "<?xml version=\"1.0\"?>\n<!-- autocal calibration: fixed joints, each sensor's origin "
         "in its parent link\n     (rpy: R = Rz(y) Ry(p) Rx(r)).\n"
      << Clocks(r, "     ") << "-->\n<robot name=\"autocal_calibration\">\n";
  out << "  <link name=\"" << (tree.empty() ? o.imu_frame : tree.front().parent) << "\"/>\n";
  for (const Transform& t : tree) {
    out << "  <link name=\"" << t.child << "\"/>\n"
        << "  <joint name=\"" << t.child << "_joint\" type=\"fixed\">\n"
        << "    <parent link=\"" << t.parent << "\"/>\n"
        << "    <child link=\"" << t.child << "\"/>\n"
        << "    <origin xyz=\"" << Vector(t.T.p, " ") << "\" rpy=\"" << Vector(Rpy(t.T.q), " ")
        << "\"/>\n  </joint>\n";
  }
  out << "</robot>\n";
  return out.str();
}

std::string Ros2StaticTf(const CalibrationFile& r, const ExportOptions& o, double below_axle_m) {
  std::ostringstream out;
  out << "#!/bin/sh\n# autocal calibration: one static transform per sensor (ROS 2 Humble or "
         "later).\n"
      << Clocks(r, "# ");
  for (const Transform& t : Tree(r, o, below_axle_m)) {
    const Eigen::Quaterniond q = t.T.q.normalized();
    out << "ros2 run tf2_ros static_transform_publisher --x " << FormatDouble(t.T.p.x()) << " --y "
        << FormatDouble(t.T.p.y()) << " --z " << FormatDouble(t.T.p.z()) << " --qx "
        << FormatDouble(q.x()) << " --qy " << FormatDouble(q.y()) << " --qz " << FormatDouble(q.z())
        << " --qw " << FormatDouble(q.w()) << " --frame-id " << t.parent << " --child-frame-id "
        << t.child << " &\n";
  }
  out << "wait\n";
  return out.str();
}

}  // namespace

ExportFormat ParseExportFormat(const std::string& name) {
  if (name == "kalibr") return ExportFormat::kKalibr;
  if (name == "fast_lio") return ExportFormat::kFastLio;
  if (name == "lio_sam") return ExportFormat::kLioSam;
  if (name == "autoware") return ExportFormat::kAutoware;
  if (name == "urdf") return ExportFormat::kUrdf;
  if (name == "ros2_static_tf") return ExportFormat::kRos2StaticTf;
  throw Error("unknown export format '" + name +
              "' (known: kalibr, fast_lio, lio_sam, autoware, urdf, ros2_static_tf)");
}

std::string ExportCalibration(const CalibrationFile& result, ExportFormat format,
                              const ExportOptions& options) {
  for (const std::string* name :
       {&options.vehicle_frame, &options.imu_frame, &options.lidar_frame, &options.gnss_frame}) {
    CheckFrameName(*name);
  }
  const bool radii = result.uncertainty.wheel_radius_left_m.sigma.has_value() &&
                     result.uncertainty.wheel_radius_right_m.sigma.has_value();
  const double mean_radius_m =
      0.5 * (result.value.wheel_radius_left_m + result.value.wheel_radius_right_m);
  const bool below_from_radius = !options.base_link_below_axle_m && radii;
  double below_axle_m = options.base_link_below_axle_m.value_or(0.0);
  switch (format) {
    case ExportFormat::kKalibr:
      return Kalibr(result);
    case ExportFormat::kFastLio:
      return FastLio(result);
    case ExportFormat::kLioSam:
      return LioSam(result);
    case ExportFormat::kAutoware:
      if (below_from_radius) below_axle_m = mean_radius_m;
      return Autoware(result, options, below_axle_m, below_from_radius);
    case ExportFormat::kUrdf:
      return Urdf(result, options, below_axle_m);
    case ExportFormat::kRos2StaticTf:
      return Ros2StaticTf(result, options, below_axle_m);
  }
  throw Error("ExportCalibration: unknown format");
}

}  // namespace io
}  // namespace autocal
