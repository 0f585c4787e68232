#include "autocal/io/problem_yaml.h"

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/io/calibration_block_fields.h"
#include "autocal/sensors/calibration_blocks.h"
#include "io/text_format.h"
#include "io/yaml_util.h"

namespace autocal {
namespace io {
namespace {

using internal::YamlFile;

// The key node of `key` in a map ExpectMap has checked (for messages that point at the key).
YAML::Node KeyNode(const YAML::Node& map, const std::string& key) {
  for (const auto& entry : map) {
    if (entry.first.Scalar() == key) return entry.first;
  }
  return map;
}

// Whole number within [min_value, max_value].
int IntInRange(const YamlFile& file, const YAML::Node& node, const std::string& what,
               int64_t min_value, int64_t max_value) {
  const int64_t value = file.Int(node, what);
  if (value < min_value || value > max_value) {
    file.Fail(node, what + ": must be within [" + std::to_string(min_value) + ", " +
                        std::to_string(max_value) + "], found " + node.Scalar());
  }
  return static_cast<int>(value);
}

// The range of a prior sigma by its key: rotations in degrees, lengths in metres, the time
// offset in seconds, speed scales without a unit (problems/README.md).
struct SigmaRange {
  double min_value;
  double max_value;
  const char* unit;
};
SigmaRange SigmaRangeOf(const std::string& sigma_key) {
  if (sigma_key == "prior_sigma_deg") return {1e-6, 180.0, "deg"};
  if (sigma_key == "prior_sigma_s") return {1e-9, 10.0, "s"};
  if (sigma_key == "prior_sigma") return {1e-6, 1.0, "(a scale factor)"};
  return {1e-6, 100.0, "m"};
}

double Sigma(const YamlFile& file, const YAML::Node& node, const std::string& what,
             const std::string& sigma_key) {
  const SigmaRange range = SigmaRangeOf(sigma_key);
  return file.DoubleInRange(node, what, range.min_value, range.max_value, range.unit);
}

// "estimate" | "fixed" | {<sigma_key>: sigma}. Returns true for the prior form, leaving the
// sigma node in *sigma_node.
bool ParseMode(const YamlFile& file, const YAML::Node& node, const std::string& what,
               const char* sigma_key, const char* sigma_form, BlockMode* mode,
               YAML::Node* sigma_node) {
  const std::string expected =
      "expected estimate, fixed or {" + std::string(sigma_key) + ": " + sigma_form + "}";
  if (node.IsScalar()) {
    const std::string& text = node.Scalar();
    if (text == "estimate") {
      *mode = BlockMode::kEstimate;
      return false;
    }
    if (text == "fixed") {
      *mode = BlockMode::kFixed;
      return false;
    }
    file.Fail(node, what + ": " + expected + ", found " + internal::Quote(text));
  }
  if (!node.IsMap()) file.Fail(node, what + ": " + expected);
  file.ExpectMap(node, what, {sigma_key});
  *mode = BlockMode::kPrior;
  *sigma_node = file.Required(node, what, sigma_key);
  return true;
}

ScalarBlockSetting ParseScalarBlock(const YamlFile& file, const YAML::Node& node,
                                    const std::string& what, const char* sigma_key) {
  ScalarBlockSetting setting;
  YAML::Node sigma;
  if (ParseMode(file, node, what, sigma_key, "sigma", &setting.mode, &sigma)) {
    setting.prior_sigma = Sigma(file, sigma, what + "." + sigma_key, sigma_key);
  }
  return setting;
}

// The prior sigma of a vector block: one number for every axis or [x, y, z], each > 0.
VectorBlockSetting ParseVectorBlock(const YamlFile& file, const YAML::Node& node,
                                    const std::string& what, const char* sigma_key) {
  VectorBlockSetting setting;
  YAML::Node sigma;
  if (ParseMode(file, node, what, sigma_key, "sigma or [x, y, z]", &setting.mode, &sigma)) {
    const std::string name = what + "." + sigma_key;
    if (sigma.IsScalar()) {
      setting.prior_sigma = Eigen::Vector3d::Constant(Sigma(file, sigma, name, sigma_key));
    } else {
      file.Vector3(sigma, name);  // the shape: a list of three numbers
      for (int i = 0; i < 3; ++i) {
        setting.prior_sigma[i] =
            Sigma(file, sigma[i], name + "[" + std::to_string(i) + "]", sigma_key);
      }
    }
  }
  return setting;
}

PoseBlockSetting ParsePoseBlock(const YamlFile& file, const YAML::Node& node,
                                const std::string& what) {
  file.ExpectMap(node, what, {"rotation", "translation"});
  PoseBlockSetting setting;
  if (const YAML::Node n = node["rotation"])
    setting.rotation = ParseVectorBlock(file, n, what + ".rotation", "prior_sigma_deg");
  if (const YAML::Node n = node["translation"])
    setting.translation = ParseVectorBlock(file, n, what + ".translation", "prior_sigma_m");
  return setting;
}

bool SameSetting(const ScalarBlockSetting& a, const ScalarBlockSetting& b) {
  return a.mode == b.mode && a.prior_sigma == b.prior_sigma;
}

ProblemSensors ParseSensors(const YamlFile& file, const YAML::Node& node) {
  file.ExpectMap(node, "sensors", {"imu", "lidar", "wheel", "gnss"});
  ProblemSensors sensors;
  if (const YAML::Node n = node["imu"]) {
    if (!file.Bool(n, "sensors.imu"))
      file.Fail(n, "sensors.imu: the IMU always takes part (the state lives in its frame)");
  }
  if (const YAML::Node n = node["lidar"]) sensors.lidar = file.Bool(n, "sensors.lidar");
  if (const YAML::Node n = node["wheel"]) sensors.wheel = file.Bool(n, "sensors.wheel");
  if (const YAML::Node n = node["gnss"]) sensors.gnss = file.Bool(n, "sensors.gnss");
  if (!sensors.lidar && !sensors.wheel && !sensors.gnss) {
    file.Fail(node, "sensors: the IMU alone calibrates nothing; enable lidar, wheel or gnss");
  }
  return sensors;
}

// Rejects `key` in `map` when its sensor does not take part.
void RejectWithoutSensor(const YamlFile& file, const YAML::Node& map, const std::string& section,
                         const char* key, bool sensor_enabled, const char* sensor) {
  if (sensor_enabled || !map[key]) return;
  const std::string name = section.empty() ? std::string(key) : section + "." + key;
  file.Fail(KeyNode(map, key), name + ": sensors." + sensor +
                                   " is false, so this setting has no effect (remove it or "
                                   "enable the sensor)");
}

// Blocks of a sensor that does not take part enter no factor: they are held fixed.
void FixBlocksOfAbsentSensors(const ProblemSensors& sensors, ProblemCalibration* c) {
  const ScalarBlockSetting fixed_scalar{BlockMode::kFixed, 0.0};
  const VectorBlockSetting fixed_vector{BlockMode::kFixed, Eigen::Vector3d::Zero()};
  if (!sensors.lidar) {
    c->T_I_L = {fixed_vector, fixed_vector};
    c->time_offset_lidar_imu_s = fixed_scalar;
  }
  if (!sensors.wheel) {
    c->wheel_radius_left_m = fixed_scalar;
    c->wheel_radius_right_m = fixed_scalar;
    c->track_width_m = fixed_scalar;
    c->T_I_V = {fixed_vector, fixed_vector};
    c->wheel_speed_scale_left = fixed_scalar;
    c->wheel_speed_scale_right = fixed_scalar;
    c->odometry_speed_scale = fixed_scalar;
    c->effective_track_m = fixed_scalar;
    c->time_offset_wheel_imu_s = fixed_scalar;
  }
  if (!sensors.gnss) {
    c->p_I_A_m = fixed_vector;
    c->time_offset_gnss_imu_s = fixed_scalar;
  }
}

ProblemCalibration ParseCalibration(const YamlFile& file, const YAML::Node& node,
                                    const ProblemSensors& sensors) {
  const std::string what = "calibration";
  file.ExpectMap(node, what,
                 {"T_I_L", "time_offset_lidar_imu_s", "wheel_radius_left_m", "wheel_radius_right_m",
                  "wheel_radius_shared", "track_width_m", "p_I_A_m", "T_I_V",
                  "wheel_speed_scale_left", "wheel_speed_scale_right", "odometry_speed_scale",
                  "effective_track_m", "time_offset_wheel_imu_s", "time_offset_gnss_imu_s",
                  "ground_tilt_sigma_deg", "roll_pitch_rate_sigma_rad_s"});
  for (const char* key : {"T_I_L", "time_offset_lidar_imu_s"})
    RejectWithoutSensor(file, node, what, key, sensors.lidar, "lidar");
  for (const char* key :
       {"wheel_radius_left_m", "wheel_radius_right_m", "wheel_radius_shared", "track_width_m",
        "T_I_V", "wheel_speed_scale_left", "wheel_speed_scale_right", "odometry_speed_scale",
        "effective_track_m", "time_offset_wheel_imu_s", "ground_tilt_sigma_deg",
        "roll_pitch_rate_sigma_rad_s"})
    RejectWithoutSensor(file, node, what, key, sensors.wheel, "wheel");
  for (const char* key : {"p_I_A_m", "time_offset_gnss_imu_s"})
    RejectWithoutSensor(file, node, what, key, sensors.gnss, "gnss");

  ProblemCalibration c;
  if (const YAML::Node n = node["T_I_L"]) c.T_I_L = ParsePoseBlock(file, n, "calibration.T_I_L");
  if (const YAML::Node n = node["time_offset_lidar_imu_s"]) {
    c.time_offset_lidar_imu_s =
        ParseScalarBlock(file, n, "calibration.time_offset_lidar_imu_s", "prior_sigma_s");
  }
  const YAML::Node left = node["wheel_radius_left_m"];
  const YAML::Node right = node["wheel_radius_right_m"];
  if (left) {
    c.wheel_radius_left_m =
        ParseScalarBlock(file, left, "calibration.wheel_radius_left_m", "prior_sigma_m");
  }
  if (right) {
    c.wheel_radius_right_m =
        ParseScalarBlock(file, right, "calibration.wheel_radius_right_m", "prior_sigma_m");
  }
  if (const YAML::Node n = node["wheel_radius_shared"]) {
    c.wheel_radius_shared = file.Bool(n, "calibration.wheel_radius_shared");
  }
  if (c.wheel_radius_shared) {
    // One parameter serves both wheels: a setting given for one side applies to both.
    if (left && !right) c.wheel_radius_right_m = c.wheel_radius_left_m;
    if (right && !left) c.wheel_radius_left_m = c.wheel_radius_right_m;
    if (!SameSetting(c.wheel_radius_left_m, c.wheel_radius_right_m)) {
      file.Fail(right,
                "calibration.wheel_radius_right_m: wheel_radius_shared is true, so both "
                "radii are one parameter and need the same setting");
    }
  }
  if (const YAML::Node n = node["track_width_m"])
    c.track_width_m = ParseScalarBlock(file, n, "calibration.track_width_m", "prior_sigma_m");
  if (const YAML::Node n = node["p_I_A_m"])
    c.p_I_A_m = ParseVectorBlock(file, n, "calibration.p_I_A_m", "prior_sigma_m");
  if (const YAML::Node n = node["T_I_V"]) c.T_I_V = ParsePoseBlock(file, n, "calibration.T_I_V");
  const std::pair<const char*, ScalarBlockSetting*> wheel_form_blocks[] = {
      {"wheel_speed_scale_left", &c.wheel_speed_scale_left},
      {"wheel_speed_scale_right", &c.wheel_speed_scale_right},
      {"odometry_speed_scale", &c.odometry_speed_scale}};
  for (const auto& [key, setting] : wheel_form_blocks) {
    if (const YAML::Node n = node[key])
      *setting = ParseScalarBlock(file, n, std::string("calibration.") + key, "prior_sigma");
  }
  if (const YAML::Node n = node["effective_track_m"]) {
    c.effective_track_m =
        ParseScalarBlock(file, n, "calibration.effective_track_m", "prior_sigma_m");
  }
  const std::pair<const char*, ScalarBlockSetting*> clock_blocks[] = {
      {"time_offset_wheel_imu_s", &c.time_offset_wheel_imu_s},
      {"time_offset_gnss_imu_s", &c.time_offset_gnss_imu_s}};
  for (const auto& [key, setting] : clock_blocks) {
    if (const YAML::Node n = node[key])
      *setting = ParseScalarBlock(file, n, std::string("calibration.") + key, "prior_sigma_s");
  }
  if (const YAML::Node n = node["ground_tilt_sigma_deg"]) {
    if (n.IsScalar() && n.Scalar() == "none") {
      c.ground_tilt_sigma_deg.reset();
    } else {
      c.ground_tilt_sigma_deg =
          file.DoubleInRange(n, "calibration.ground_tilt_sigma_deg", 0.01, 30.0, "deg (or none)");
    }
  }
  if (const YAML::Node n = node["roll_pitch_rate_sigma_rad_s"]) {
    if (n.IsScalar() && n.Scalar() == "measured") {
      c.roll_pitch_rate_sigma_rad_s = 0.0;
    } else if (!(n.IsScalar() && n.Scalar() == "none")) {
      c.roll_pitch_rate_sigma_rad_s = file.DoubleInRange(
          n, "calibration.roll_pitch_rate_sigma_rad_s", 1e-4, 10.0, "rad/s (or measured, none)");
    }
  }
  return c;
}

factors::LossOptions ParseLoss(const YamlFile& file, const YAML::Node& node,
                               const std::string& what) {
  const std::string text = file.String(node, what);
  try {
    return factors::ParseLossOptions(text);
  } catch (const Error& e) {
    file.Fail(node, what + ": " + e.what() + "; write none, huber:<scale> or cauchy:<scale>");
  }
}

factors::FactorLossOptions ParseLosses(const YamlFile& file, const YAML::Node& node,
                                       const ProblemSensors& sensors) {
  file.ExpectMap(node, "loss", {"imu", "prior", "wheel", "gnss", "lidar"});
  RejectWithoutSensor(file, node, "loss", "lidar", sensors.lidar, "lidar");
  RejectWithoutSensor(file, node, "loss", "wheel", sensors.wheel, "wheel");
  RejectWithoutSensor(file, node, "loss", "gnss", sensors.gnss, "gnss");
  factors::FactorLossOptions loss;
  if (const YAML::Node n = node["imu"]) loss.imu = ParseLoss(file, n, "loss.imu");
  if (const YAML::Node n = node["prior"]) loss.prior = ParseLoss(file, n, "loss.prior");
  if (const YAML::Node n = node["wheel"]) loss.wheel = ParseLoss(file, n, "loss.wheel");
  if (const YAML::Node n = node["gnss"]) loss.gnss = ParseLoss(file, n, "loss.gnss");
  if (const YAML::Node n = node["lidar"]) loss.lidar = ParseLoss(file, n, "loss.lidar");
  return loss;
}

// Upper bounds that catch typos (an extra digit) rather than limit real use.
constexpr int64_t kMaxWindowSize = 10000;
constexpr int64_t kMaxIterations = 100000;
constexpr int64_t kMaxThreads = 1024;
constexpr int64_t kMaxPointsPerSweep = 10000000;
constexpr int64_t kMaxSweepStride = 100;
// A residual voxel below 1 cm is finer than the LiDAR's range noise, one above 20 m leaves a
// handful of points per sweep; the window's range limit below 1 m keeps no point.
constexpr double kMinVoxelM = 0.01;
constexpr double kMaxVoxelM = 20.0;
constexpr double kMinWindowRangeM = 1.0;
constexpr double kMaxWindowRangeM = 10000.0;

// Bounds of the timing settings: a gap under 1 ms brackets no sample of a 1000 Hz IMU, one over
// a minute bridges any outage; a keyframe period below 5 ms is finer than any IMU needs.
constexpr double kMinGapS = 1e-3;
constexpr double kMaxGapS = 60.0;
constexpr double kMinKeyframePeriodS = 0.005;
constexpr double kMaxKeyframePeriodS = 10.0;
constexpr double kMinHalfWidthS = 0.1;

ProblemTiming ParseTiming(const YamlFile& file, const YAML::Node& node,
                          const ProblemSensors& sensors) {
  file.ExpectMap(node, "timing",
                 {"max_imu_gap_s", "max_wheel_gap_s", "max_fix_gap_s", "keyframe_period_s",
                  "gnss_track_half_width_s", "min_factor_fraction"});
  RejectWithoutSensor(file, node, "timing", "max_wheel_gap_s", sensors.wheel, "wheel");
  RejectWithoutSensor(file, node, "timing", "max_fix_gap_s", sensors.gnss, "gnss");
  RejectWithoutSensor(file, node, "timing", "gnss_track_half_width_s", sensors.gnss, "gnss");
  if (sensors.lidar && node["keyframe_period_s"]) {
    file.Fail(KeyNode(node, "keyframe_period_s"),
              "timing.keyframe_period_s: sensors.lidar is true, so the keyframes are the LiDAR "
              "sweeps and this setting has no effect (remove it or disable the LiDAR)");
  }
  ProblemTiming timing;
  const auto seconds = [&](const char* key, double min_s, double max_s,
                           std::optional<double>* value) {
    if (const YAML::Node n = node[key]) {
      *value = file.DoubleInRange(n, std::string("timing.") + key, min_s, max_s, "s");
    }
  };
  seconds("max_imu_gap_s", kMinGapS, kMaxGapS, &timing.max_imu_gap_s);
  seconds("max_wheel_gap_s", kMinGapS, kMaxGapS, &timing.max_wheel_gap_s);
  seconds("max_fix_gap_s", kMinGapS, kMaxGapS, &timing.max_fix_gap_s);
  seconds("keyframe_period_s", kMinKeyframePeriodS, kMaxKeyframePeriodS, &timing.keyframe_period_s);
  seconds("gnss_track_half_width_s", kMinHalfWidthS, kMaxGapS, &timing.gnss_track_half_width_s);
  if (const YAML::Node n = node["min_factor_fraction"]) {
    timing.min_factor_fraction = file.DoubleInRange(n, "timing.min_factor_fraction", 0.0, 1.0,
                                                    "(a fraction of the keyframes)");
  }
  return timing;
}

Problem ParseProblem(const YamlFile& file) {
  const YAML::Node& root = file.root();
  file.ExpectMap(
      root, "problem",
      {"description", "sensors", "calibration", "loss", "window", "solver", "lidar", "timing"});
  Problem problem;
  problem.path = file.path();
  if (const YAML::Node n = root["description"]) problem.description = file.String(n, "description");
  if (const YAML::Node n = root["sensors"]) problem.sensors = ParseSensors(file, n);
  if (const YAML::Node n = root["calibration"])
    problem.calibration = ParseCalibration(file, n, problem.sensors);
  FixBlocksOfAbsentSensors(problem.sensors, &problem.calibration);
  if (const YAML::Node n = root["loss"]) problem.loss = ParseLosses(file, n, problem.sensors);
  if (const YAML::Node window = root["window"]) {
    file.ExpectMap(window, "window", {"size", "max_range_m"});
    if (const YAML::Node n = window["size"])
      problem.window_size = IntInRange(file, n, "window.size", 2, kMaxWindowSize);
    RejectWithoutSensor(file, window, "window", "max_range_m", problem.sensors.lidar, "lidar");
    if (const YAML::Node n = window["max_range_m"]) {
      problem.window_max_range_m = file.Double(n, "window.max_range_m");
      if (problem.window_max_range_m != 0.0 && !(problem.window_max_range_m >= kMinWindowRangeM &&
                                                 problem.window_max_range_m <= kMaxWindowRangeM)) {
        file.Fail(n, "window.max_range_m: must be 0 (no limit) or within [" +
                         internal::FormatDouble(kMinWindowRangeM) + ", " +
                         internal::FormatDouble(kMaxWindowRangeM) + "] m, found " + n.Scalar());
      }
    }
  }
  if (const YAML::Node solver = root["solver"]) {
    file.ExpectMap(solver, "solver", {"max_iterations", "outer_iterations", "num_threads"});
    ProblemSolver& s = problem.solver;
    if (const YAML::Node n = solver["max_iterations"])
      s.max_iterations = IntInRange(file, n, "solver.max_iterations", 1, kMaxIterations);
    if (const YAML::Node n = solver["outer_iterations"])
      s.outer_iterations = IntInRange(file, n, "solver.outer_iterations", 1, kMaxIterations);
    if (const YAML::Node n = solver["num_threads"])
      s.num_threads = IntInRange(file, n, "solver.num_threads", 1, kMaxThreads);
  }
  RejectWithoutSensor(file, root, "", "lidar", problem.sensors.lidar, "lidar");
  if (const YAML::Node lidar = root["lidar"]) {
    file.ExpectMap(lidar, "lidar", {"max_points_per_sweep", "voxel_m", "sweep_stride"});
    if (const YAML::Node n = lidar["max_points_per_sweep"]) {
      problem.lidar.max_points_per_sweep =
          IntInRange(file, n, "lidar.max_points_per_sweep", 1, kMaxPointsPerSweep);
    }
    if (const YAML::Node n = lidar["voxel_m"]) {
      problem.lidar.voxel_m = file.DoubleInRange(n, "lidar.voxel_m", kMinVoxelM, kMaxVoxelM, "m");
    }
    if (const YAML::Node n = lidar["sweep_stride"])
      problem.lidar.sweep_stride = IntInRange(file, n, "lidar.sweep_stride", 1, kMaxSweepStride);
  }
  if (const YAML::Node n = root["timing"]) problem.timing = ParseTiming(file, n, problem.sensors);
  return problem;
}

}  // namespace

const char* BlockModeName(BlockMode mode) {
  switch (mode) {
    case BlockMode::kEstimate:
      return "estimate";
    case BlockMode::kFixed:
      return "fixed";
    case BlockMode::kPrior:
      return "prior";
  }
  return "unknown";
}

Problem ReadProblemYaml(const std::string& path) {
  const YamlFile file(path);
  return ParseProblem(file);
}

ProblemCalibration WithEveryBlockFixed(ProblemCalibration c) {
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    SetBlockSetting(block.id, {BlockMode::kFixed, Eigen::VectorXd::Zero(block.tangent_size)}, &c);
  }
  return c;
}

}  // namespace io
}  // namespace autocal
