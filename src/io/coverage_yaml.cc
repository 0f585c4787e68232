#include "autocal/io/coverage_yaml.h"

#include <cmath>
#include <filesystem>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/geometry/roll_pitch_yaw.h"
#include "autocal/geometry/se3.h"
#include "autocal/io/calibration_yaml.h"
#include "yaml_util.h"

namespace autocal {
namespace io {
namespace {

using internal::YamlFile;

coverage::SensorType SensorTypeOf(const YamlFile& f, const YAML::Node& node) {
  const std::string name = f.String(node, "type");
  if (name == "lidar") return coverage::SensorType::kLidar;
  if (name == "camera") return coverage::SensorType::kCamera;
  if (name == "radar") return coverage::SensorType::kRadar;
  if (name == "ultrasonic") return coverage::SensorType::kUltrasonic;
  f.Fail(node, "type must be lidar, camera, radar or ultrasonic, got '" + name + "'");
}

// The LiDAR's pose in the ground frame from a calibration result: T_V_L = T_V_I T_I_L,
// raised by the axle height.
void PlaceFromCalibration(const YamlFile& f, const YAML::Node& rig, const YAML::Node& node,
                          coverage::Sensor* sensor) {
  const YAML::Node from = node["pose_from_calibration"];
  if (f.String(from, "pose_from_calibration") != "lidar") {
    f.Fail(from, "pose_from_calibration: only 'lidar' is an exteroceptive sensor of a result");
  }
  if (!rig["calibration"]) f.Fail(node, "pose_from_calibration needs the rig's calibration key");
  const YAML::Node c = rig["calibration"];
  f.ExpectMap(c, "calibration", {"file", "axle_height_m"});
  std::filesystem::path file = f.String(f.Required(c, "calibration", "file"), "calibration.file");
  if (file.is_relative()) file = std::filesystem::path(f.path()).parent_path() / file;
  const CalibrationFile result = ReadCalibrationYaml(file.string());
  double axle_height_m = 0.0;
  if (c["axle_height_m"]) {
    axle_height_m = f.DoubleInRange(c["axle_height_m"], "calibration.axle_height_m", 0.0, 5.0, "m");
  } else if (result.uncertainty.wheel_radius_left_m.sigma &&
             result.uncertainty.wheel_radius_right_m.sigma) {
    axle_height_m = 0.5 * (result.value.wheel_radius_left_m + result.value.wheel_radius_right_m);
  } else {
    f.Fail(c, "calibration: the result estimated no wheel radius; give axle_height_m");
  }
  const sensors::Calibration& v = result.value;
  const geometry::Pose3d T_V_L =
      geometry::Pose3d(v.q_I_V, v.p_I_V).Inverse() * geometry::Pose3d(v.q_I_L, v.p_I_L);
  const Eigen::Vector3d rpy = geometry::RollPitchYaw(T_V_L.q);
  sensor->position_m = T_V_L.p + Eigen::Vector3d(0.0, 0.0, axle_height_m);
  sensor->yaw_rad = rpy(2);
  sensor->pitch_rad = rpy(1);
}

coverage::Sensor ReadSensor(const YamlFile& f, const YAML::Node& rig, const YAML::Node& node) {
  f.ExpectMap(node, "sensor",
              {"name", "type", "position_m", "pose_from_calibration", "yaw_deg", "pitch_deg",
               "hfov_deg", "vfov_deg", "range_m", "min_range_m"});
  coverage::Sensor s;
  s.name = f.String(f.Required(node, "sensor", "name"), "name");
  s.type = SensorTypeOf(f, f.Required(node, "sensor " + s.name, "type"));
  if (node["pose_from_calibration"]) {
    if (node["position_m"] || node["yaw_deg"] || node["pitch_deg"]) {
      f.Fail(node, "sensor " + s.name +
                       ": give pose_from_calibration or position_m/yaw_deg/"
                       "pitch_deg, not both");
    }
    PlaceFromCalibration(f, rig, node, &s);
  } else {
    s.position_m = f.Vector3(f.Required(node, "sensor " + s.name, "position_m"), "position_m");
    if (node["yaw_deg"]) {
      s.yaw_rad = kDegToRad * f.DoubleInRange(node["yaw_deg"], "yaw_deg", -360, 360, "deg");
    }
    if (node["pitch_deg"]) {
      s.pitch_rad = kDegToRad * f.DoubleInRange(node["pitch_deg"], "pitch_deg", -90, 90, "deg");
    }
  }
  s.hfov_rad = kDegToRad * f.DoubleInRange(f.Required(node, "sensor " + s.name, "hfov_deg"),
                                           "hfov_deg", 0.1, 360, "deg");
  const YAML::Node vfov = f.Required(node, "sensor " + s.name, "vfov_deg");
  if (!vfov.IsSequence() || vfov.size() != 2) f.Fail(vfov, "vfov_deg: [lowest, highest] in deg");
  s.vfov_min_rad = kDegToRad * f.DoubleInRange(vfov[0], "vfov_deg", -90, 90, "deg");
  s.vfov_max_rad = kDegToRad * f.DoubleInRange(vfov[1], "vfov_deg", -90, 90, "deg");
  if (!(s.vfov_max_rad > s.vfov_min_rad)) f.Fail(vfov, "vfov_deg: the lowest must be below");
  s.range_m =
      f.DoubleInRange(f.Required(node, "sensor " + s.name, "range_m"), "range_m", 0.1, 2000, "m");
  if (node["min_range_m"]) {
    s.min_range_m = f.DoubleInRange(node["min_range_m"], "min_range_m", 0.0, s.range_m, "m");
  }
  return s;
}

}  // namespace

coverage::Rig ReadRigYaml(const std::string& path) {
  const YamlFile f(path);
  const YAML::Node& root = f.root();
  f.ExpectMap(root, "rig", {"name", "body", "calibration", "sensors"});
  coverage::Rig rig;
  rig.name =
      root["name"] ? f.String(root["name"], "name") : std::filesystem::path(path).stem().string();
  const YAML::Node body = f.Required(root, "rig", "body");
  f.ExpectMap(body, "body", {"rear_m", "front_m", "half_width_m", "height_m"});
  rig.body.rear_m = f.DoubleInRange(f.Required(body, "body", "rear_m"), "rear_m", -20, 0, "m");
  rig.body.front_m = f.DoubleInRange(f.Required(body, "body", "front_m"), "front_m", 0, 30, "m");
  rig.body.half_width_m =
      f.DoubleInRange(f.Required(body, "body", "half_width_m"), "half_width_m", 0.1, 5, "m");
  rig.body.height_m =
      f.DoubleInRange(f.Required(body, "body", "height_m"), "height_m", 0.1, 10, "m");
  const YAML::Node sensors = f.Required(root, "rig", "sensors");
  if (!sensors.IsSequence() || sensors.size() == 0) f.Fail(sensors, "sensors: a list of sensors");
  for (const YAML::Node& node : sensors) rig.sensors.push_back(ReadSensor(f, root, node));
  return rig;
}

coverage::Scenario ReadScenarioYaml(const std::string& path) {
  const YamlFile f(path);
  const YAML::Node& root = f.root();
  f.ExpectMap(root, "scenario",
              {"name", "speed_kmh", "aggressive_deceleration_m_s2", "normal_deceleration_m_s2",
               "reaction_time_s", "lane_width_m", "time_gap_s", "side_range_m", "rear_range_m",
               "overtake_time_s", "omni_range_m", "roundabout_range_m", "target_height_m",
               "min_covered_fraction", "maneuvers"});
  coverage::Scenario s;
  s.name =
      root["name"] ? f.String(root["name"], "name") : std::filesystem::path(path).stem().string();
  s.speed_m_s =
      f.DoubleInRange(f.Required(root, "scenario", "speed_kmh"), "speed_kmh", 1, 400, "km/h") / 3.6;
  const auto optional = [&](const char* key, double* value, double lo, double hi,
                            const char* unit) {
    if (root[key]) *value = f.DoubleInRange(root[key], key, lo, hi, unit);
  };
  optional("aggressive_deceleration_m_s2", &s.aggressive_deceleration_m_s2, 0.1, 20, "m/s^2");
  optional("normal_deceleration_m_s2", &s.normal_deceleration_m_s2, 0.1, 20, "m/s^2");
  optional("reaction_time_s", &s.reaction_time_s, 0, 10, "s");
  optional("lane_width_m", &s.lane_width_m, 1, 10, "m");
  optional("time_gap_s", &s.time_gap_s, 0, 10, "s");
  optional("side_range_m", &s.side_range_m, 1, 500, "m");
  optional("rear_range_m", &s.rear_range_m, 1, 500, "m");
  optional("overtake_time_s", &s.overtake_time_s, 0.5, 60, "s");
  optional("omni_range_m", &s.omni_range_m, 1, 500, "m");
  optional("roundabout_range_m", &s.roundabout_range_m, 1, 500, "m");
  optional("target_height_m", &s.target_height_m, 0, 5, "m");
  optional("min_covered_fraction", &s.min_covered_fraction, 0, 1, "");
  const YAML::Node maneuvers = f.Required(root, "scenario", "maneuvers");
  if (!maneuvers.IsSequence() || maneuvers.size() == 0) {
    f.Fail(maneuvers, "maneuvers: a list such as [emergency_stop, maintain_speed]");
  }
  for (const YAML::Node& m : maneuvers) s.maneuvers.push_back(f.String(m, "maneuvers"));
  try {
    coverage::Requirements(s, coverage::Body());
  } catch (const Error& e) {
    f.Fail(maneuvers, e.what());
  }
  return s;
}

coverage::Scenario ScenarioPreset(const std::string& name) {
  coverage::Scenario s;
  s.name = name;
  if (name == "highway") {
    s.speed_m_s = 120.0 / 3.6;
    s.maneuvers = {"emergency_stop", "maintain_speed", "lane_change"};
  } else if (name == "urban") {
    s.speed_m_s = 50.0 / 3.6;
    s.maneuvers = {"emergency_stop", "maintain_speed", "lane_change",
                   "overtake",       "intersection",   "roundabout"};
  } else {
    throw Error("unknown scenario '" + name + "' (highway, urban, or a scenario file)");
  }
  return s;
}

}  // namespace io
}  // namespace autocal
