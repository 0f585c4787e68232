#include "autocal/io/calibration_yaml.h"

#include <cmath>
#include <string>
#include <string_view>
#include <utility>

#include "autocal/common/error.h"
#include "io/calibration_node.h"
#include "io/text_format.h"
#include "io/yaml_util.h"

namespace autocal {
namespace io {
namespace internal {
namespace {

// What a file written by WriteCalibrationYaml states about itself: the format on its first
// key, this comment as its last line. Either missing means the file was cut.
constexpr const char* kFormat = "autocal_calibration_1";
constexpr std::string_view kEndMarker = "# end of autocal calibration\n";
constexpr const char* kBlocks[] = {"T_I_L",
                                   "time_offset_lidar_imu_s",
                                   "wheel_radius_left_m",
                                   "wheel_radius_right_m",
                                   "track_width_m",
                                   "p_I_A_m",
                                   "T_I_V"};

// A file that says it is a written result must hold all of it: the end marker as its last
// bytes and every calibration block (a cut file would otherwise read as defaults).
void CheckWholeResult(const YamlFile& file, const YAML::Node& root) {
  const std::string bytes = ReadFileBytes(file.path());
  const size_t size = bytes.size();
  if (size < kEndMarker.size() ||
      std::string_view(bytes).substr(size - kEndMarker.size()) != kEndMarker) {
    throw ParseError(SourceLocation{file.path(), 0, 0, static_cast<int64_t>(size)},
                     "the file ends without its last line '# end of autocal calibration': it "
                     "was cut short (a run stopped while writing?)");
  }
  for (const char* block : kBlocks) {
    if (!root[block]) {
      file.Fail(root, std::string("block '") + block + "' is missing; a file of format " + kFormat +
                          " holds every block");
    }
  }
}

std::string Join(const std::string& prefix, const char* key) {
  return prefix.empty() ? std::string(key) : prefix + "." + key;
}

void ParsePose(const YamlFile& file, const YAML::Node& node, const std::string& what,
               Eigen::Quaterniond* q, Eigen::Vector3d* p, PoseBlockInfo* info) {
  file.ExpectMap(node, what, {"q_xyzw", "p_m", "sigma_rot_deg", "sigma_p_m", "observable"});
  *q = file.QuaternionXyzw(file.Required(node, what, "q_xyzw"), Join(what, "q_xyzw"));
  *p = file.Vector3(file.Required(node, what, "p_m"), Join(what, "p_m"));
  if (node["sigma_rot_deg"]) {
    info->sigma_rot_deg = file.NonNegative3(node["sigma_rot_deg"], Join(what, "sigma_rot_deg"));
  }
  if (node["sigma_p_m"])
    info->sigma_p_m = file.NonNegative3(node["sigma_p_m"], Join(what, "sigma_p_m"));
  if (node["observable"])
    info->observable = file.Observable(node["observable"], Join(what, "observable"), 6);
}

// A bare number, or {value:, sigma:, observable:}.
void ParseScalar(const YamlFile& file, const YAML::Node& node, const std::string& what,
                 bool positive, double* value, ScalarBlockInfo* info) {
  const auto read_value = [&](const YAML::Node& value_node, const std::string& name) {
    return positive ? file.Positive(value_node, name) : file.Double(value_node, name);
  };
  if (node.IsScalar()) {
    *value = read_value(node, what);
    return;
  }
  file.ExpectMap(node, what, {"value", "sigma", "observable"});
  *value = read_value(file.Required(node, what, "value"), Join(what, "value"));
  if (node["sigma"]) {
    info->sigma = file.Double(node["sigma"], Join(what, "sigma"));
    if (*info->sigma < 0.0)
      file.Fail(node["sigma"], Join(what, "sigma") + ": a sigma must be >= 0");
  }
  if (node["observable"])
    info->observable = file.Bool(node["observable"], Join(what, "observable"));
}

// A bare [x, y, z], or {value: [...], sigma: [...], observable:}.
void ParseVector(const YamlFile& file, const YAML::Node& node, const std::string& what,
                 Eigen::Vector3d* value, VectorBlockInfo* info) {
  if (node.IsSequence()) {
    *value = file.Vector3(node, what);
    return;
  }
  file.ExpectMap(node, what, {"value", "sigma", "observable"});
  *value = file.Vector3(file.Required(node, what, "value"), Join(what, "value"));
  if (node["sigma"]) info->sigma = file.NonNegative3(node["sigma"], Join(what, "sigma"));
  if (node["observable"])
    info->observable = file.Observable(node["observable"], Join(what, "observable"), 3);
}

// ---- writing ----

std::string Number(double value, const char* name) {
  if (!std::isfinite(value))
    throw Error(std::string("calibration value '") + name + "' is not finite");
  return FormatDouble(value);
}

std::string List(const double* values, int n, const char* name) {
  std::string out = "[";
  for (int i = 0; i < n; ++i) out += (i ? ", " : "") + Number(values[i], name);
  return out + "]";
}

std::string Flags(const std::vector<bool>& flags) {
  if (flags.size() == 1) return flags[0] ? "true" : "false";
  std::string out = "[";
  for (size_t i = 0; i < flags.size(); ++i)
    out += std::string(i ? ", " : "") + (flags[i] ? "true" : "false");
  return out + "]";
}

std::string PoseText(const std::string& pad, const char* name, const Eigen::Quaterniond& q,
                     const Eigen::Vector3d& p, const PoseBlockInfo& info) {
  std::string out = pad + name + ":\n";
  out += pad + "  q_xyzw: " + List(q.coeffs().data(), 4, name) + "\n";
  out += pad + "  p_m: " + List(p.data(), 3, name) + "\n";
  if (info.sigma_rot_deg)
    out += pad + "  sigma_rot_deg: " + List(info.sigma_rot_deg->data(), 3, name) + "\n";
  if (info.sigma_p_m) out += pad + "  sigma_p_m: " + List(info.sigma_p_m->data(), 3, name) + "\n";
  if (!info.observable.empty()) out += pad + "  observable: " + Flags(info.observable) + "\n";
  return out;
}

std::string ScalarText(const std::string& pad, const char* name, double value,
                       const ScalarBlockInfo& info) {
  std::string out = pad + name + ": {value: " + Number(value, name);
  if (info.sigma) out += ", sigma: " + Number(*info.sigma, name);
  if (info.observable) out += std::string(", observable: ") + (*info.observable ? "true" : "false");
  return out + "}\n";
}

std::string VectorText(const std::string& pad, const char* name, const Eigen::Vector3d& value,
                       const VectorBlockInfo& info) {
  std::string out = pad + name + ": {value: " + List(value.data(), 3, name);
  if (info.sigma) out += ", sigma: " + List(info.sigma->data(), 3, name);
  if (!info.observable.empty()) out += ", observable: " + Flags(info.observable);
  return out + "}\n";
}

}  // namespace

CalibrationFile ParseCalibrationNode(const YamlFile& file, const YAML::Node& node,
                                     const std::string& what) {
  file.ExpectMap(
      node, what.empty() ? "calibration" : what,
      {"format", "T_I_L", "time_offset_lidar_imu_s", "wheel_radius_left_m", "wheel_radius_right_m",
       "track_width_m", "p_I_A_m", "T_I_V", "wheel_speed_scale_left", "wheel_speed_scale_right",
       "odometry_speed_scale", "effective_track_m", "time_offset_wheel_imu_s",
       "time_offset_gnss_imu_s", "solver", "residuals"});
  if (const YAML::Node format = node["format"]) {
    if (!what.empty()) file.Fail(format, what + ".format: only a calibration file has a format");
    if (file.String(format, "format") != kFormat) {
      file.Fail(format, std::string("format: expected '") + kFormat + "', found '" +
                            file.String(format, "format") + "'");
    }
    CheckWholeResult(file, node);
  }
  CalibrationFile out;
  sensors::Calibration& c = out.value;
  CalibrationUncertainty& u = out.uncertainty;
  if (node["T_I_L"])
    ParsePose(file, node["T_I_L"], Join(what, "T_I_L"), &c.q_I_L, &c.p_I_L, &u.T_I_L);
  if (node["T_I_V"])
    ParsePose(file, node["T_I_V"], Join(what, "T_I_V"), &c.q_I_V, &c.p_I_V, &u.T_I_V);
  if (node["time_offset_lidar_imu_s"]) {
    ParseScalar(file, node["time_offset_lidar_imu_s"], Join(what, "time_offset_lidar_imu_s"), false,
                &c.time_offset_lidar_imu_s, &u.time_offset_lidar_imu_s);
  }
  if (node["wheel_radius_left_m"]) {
    ParseScalar(file, node["wheel_radius_left_m"], Join(what, "wheel_radius_left_m"), true,
                &c.wheel_radius_left_m, &u.wheel_radius_left_m);
  }
  if (node["wheel_radius_right_m"]) {
    ParseScalar(file, node["wheel_radius_right_m"], Join(what, "wheel_radius_right_m"), true,
                &c.wheel_radius_right_m, &u.wheel_radius_right_m);
  }
  if (node["track_width_m"]) {
    ParseScalar(file, node["track_width_m"], Join(what, "track_width_m"), true, &c.track_width_m,
                &u.track_width_m);
  }
  const std::pair<const char*, std::pair<double*, ScalarBlockInfo*>> wheel_form_blocks[] = {
      {"wheel_speed_scale_left", {&c.wheel_speed_scale_left, &u.wheel_speed_scale_left}},
      {"wheel_speed_scale_right", {&c.wheel_speed_scale_right, &u.wheel_speed_scale_right}},
      {"odometry_speed_scale", {&c.odometry_speed_scale, &u.odometry_speed_scale}},
      {"effective_track_m", {&c.effective_track_m, &u.effective_track_m}}};
  for (const auto& [key, fields] : wheel_form_blocks) {
    if (node[key]) ParseScalar(file, node[key], Join(what, key), true, fields.first, fields.second);
  }
  const std::pair<const char*, std::pair<double*, ScalarBlockInfo*>> clock_blocks[] = {
      {"time_offset_wheel_imu_s", {&c.time_offset_wheel_imu_s, &u.time_offset_wheel_imu_s}},
      {"time_offset_gnss_imu_s", {&c.time_offset_gnss_imu_s, &u.time_offset_gnss_imu_s}}};
  for (const auto& [key, fields] : clock_blocks) {
    if (node[key])
      ParseScalar(file, node[key], Join(what, key), false, fields.first, fields.second);
  }
  if (node["p_I_A_m"])
    ParseVector(file, node["p_I_A_m"], Join(what, "p_I_A_m"), &c.p_I_A, &u.p_I_A_m);
  if (const YAML::Node solver = node["solver"]) {
    const std::string name = Join(what, "solver");
    if (!solver.IsMap()) file.Fail(solver, name + ": expected a map of key: value");
    for (const auto& entry : solver) {
      const std::string key = file.String(entry.first, name);
      if (out.solver.count(key)) file.Fail(entry.first, name + ": key '" + key + "' appears twice");
      out.solver[key] = file.String(entry.second, name + "." + key);
    }
  }
  if (const YAML::Node residuals = node["residuals"]) {
    const std::string name = Join(what, "residuals");
    if (!residuals.IsMap())
      file.Fail(residuals, name + ": expected a map of sensor: {statistic: value}");
    for (const auto& sensor : residuals) {
      const std::string sensor_name = file.String(sensor.first, name);
      const std::string section = name + "." + sensor_name;
      if (out.residuals.count(sensor_name))
        file.Fail(sensor.first, name + ": sensor '" + sensor_name + "' appears twice");
      if (!sensor.second.IsMap())
        file.Fail(sensor.second, section + ": expected a map of statistic: number");
      std::map<std::string, double>& stats = out.residuals[sensor_name];
      for (const auto& stat : sensor.second) {
        const std::string key = file.String(stat.first, section);
        if (stats.count(key)) file.Fail(stat.first, section + ": key '" + key + "' appears twice");
        stats[key] = file.Double(stat.second, section + "." + key);
      }
    }
  }
  return out;
}

}  // namespace internal

CalibrationFile ReadCalibrationYaml(const std::string& path) {
  const internal::YamlFile file(path);
  return internal::ParseCalibrationNode(file, file.root(), "");
}

std::string CalibrationYamlText(const CalibrationFile& calibration, int indent) {
  using internal::FormatDouble;
  const std::string pad(static_cast<size_t>(indent), ' ');
  const sensors::Calibration& c = calibration.value;
  const CalibrationUncertainty& u = calibration.uncertainty;
  std::string out;
  out += internal::PoseText(pad, "T_I_L", c.q_I_L, c.p_I_L, u.T_I_L);
  out += internal::ScalarText(pad, "time_offset_lidar_imu_s", c.time_offset_lidar_imu_s,
                              u.time_offset_lidar_imu_s);
  out += internal::ScalarText(pad, "wheel_radius_left_m", c.wheel_radius_left_m,
                              u.wheel_radius_left_m);
  out += internal::ScalarText(pad, "wheel_radius_right_m", c.wheel_radius_right_m,
                              u.wheel_radius_right_m);
  out += internal::ScalarText(pad, "track_width_m", c.track_width_m, u.track_width_m);
  out += internal::VectorText(pad, "p_I_A_m", c.p_I_A, u.p_I_A_m);
  out += internal::PoseText(pad, "T_I_V", c.q_I_V, c.p_I_V, u.T_I_V);
  out += internal::ScalarText(pad, "wheel_speed_scale_left", c.wheel_speed_scale_left,
                              u.wheel_speed_scale_left);
  out += internal::ScalarText(pad, "wheel_speed_scale_right", c.wheel_speed_scale_right,
                              u.wheel_speed_scale_right);
  out += internal::ScalarText(pad, "odometry_speed_scale", c.odometry_speed_scale,
                              u.odometry_speed_scale);
  out += internal::ScalarText(pad, "effective_track_m", c.effective_track_m, u.effective_track_m);
  out += internal::ScalarText(pad, "time_offset_wheel_imu_s", c.time_offset_wheel_imu_s,
                              u.time_offset_wheel_imu_s);
  out += internal::ScalarText(pad, "time_offset_gnss_imu_s", c.time_offset_gnss_imu_s,
                              u.time_offset_gnss_imu_s);
  if (!calibration.solver.empty()) {
    out += pad + "solver:\n";
    for (const auto& [key, value] : calibration.solver) {
      out += pad + "  " + internal::YamlString(key) + ": " + internal::YamlString(value) + "\n";
    }
  }
  if (!calibration.residuals.empty()) {
    out += pad + "residuals:\n";
    for (const auto& [sensor, stats] : calibration.residuals) {
      out += pad + "  " + internal::YamlString(sensor) + ":" + (stats.empty() ? " {}\n" : "\n");
      for (const auto& [key, value] : stats) {
        out += pad + "    " + internal::YamlString(key) + ": " +
               internal::Number(value, key.c_str()) + "\n";
      }
    }
  }
  return out;
}

void WriteCalibrationYaml(const std::string& path, const CalibrationFile& calibration) {
  const std::string text =
      "# autocal calibration (schema: datasets/README.md). T_a_b maps frame b into frame a;\n"
      "# quaternions [qx, qy, qz, qw] (Hamilton); t_imu = t_sensor + time_offset_<sensor>_imu_s.\n"
      "format: " +
      std::string(internal::kFormat) + "\n" + CalibrationYamlText(calibration) +
      std::string(internal::kEndMarker);
  internal::WriteFileText(path, text);
}

}  // namespace io
}  // namespace autocal
