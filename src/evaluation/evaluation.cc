#include "autocal/evaluation/evaluation.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/units.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/csv_files.h"
#include "autocal/io/tum_trajectory.h"

namespace autocal {
namespace evaluation {
namespace {

// One line of the report. Scalars keep their sign in `value`; vectors report their norm and
// the components in `axes`. A limit applies to |value|.
struct Row {
  const char* metric = "";
  const char* unit = "";
  const char* threshold = "";
  std::optional<double> limit;
  bool measured = true;
  const char* unmeasured = "not measured";
  double value = std::numeric_limits<double>::quiet_NaN();
  std::optional<Eigen::Vector3d> axes;

  bool Exceeded() const { return limit && (!measured || std::abs(value) > *limit); }
};

Row MakeRow(const char* metric, const char* unit, const char* threshold,
            std::optional<double> limit) {
  Row row;
  row.metric = metric;
  row.unit = unit;
  row.threshold = threshold;
  row.limit = limit;
  return row;
}

std::vector<Row> Rows(const Evaluation& evaluation, const Thresholds& t) {
  const CalibrationErrors& c = evaluation.calibration;
  const EstimatedBlocks& e = evaluation.estimated;
  const auto estimated_only = [](bool estimated, Row row) {
    if (!estimated) {
      row.measured = false;
      row.unmeasured = "not estimated by the result";
    }
    return row;
  };
  const auto scalar = [&](bool estimated, const char* metric, const char* unit,
                          const char* threshold, std::optional<double> limit, double value) {
    Row row = MakeRow(metric, unit, threshold, limit);
    row.value = value;
    return estimated_only(estimated, row);
  };
  const auto vector = [&](bool estimated, const char* metric, const char* unit,
                          const char* threshold, std::optional<double> limit,
                          const Eigen::Vector3d& axes) {
    Row row = MakeRow(metric, unit, threshold, limit);
    row.value = axes.norm();
    row.axes = axes;
    return estimated_only(estimated, row);
  };
  std::vector<Row> rows = {
      vector(e.T_I_L, "T_I_L rotation", "deg", "max_rotation_deg", t.max_rotation_deg,
             c.T_I_L.rotation_deg),
      vector(e.T_I_L, "T_I_L translation", "mm", "max_translation_mm", t.max_translation_mm,
             c.T_I_L.translation_mm),
      scalar(e.time_offset, "LiDAR time offset", "ms", "max_time_offset_ms", t.max_time_offset_ms,
             c.time_offset_ms),
      scalar(e.wheel_radius_left, "wheel radius left", "%", "max_radius_percent",
             t.max_radius_percent, c.wheel_radius_left_percent),
      scalar(e.wheel_radius_right, "wheel radius right", "%", "max_radius_percent",
             t.max_radius_percent, c.wheel_radius_right_percent),
      scalar(e.track_width, "track width", "%", "max_track_width_percent",
             t.max_track_width_percent, c.track_width_percent),
      scalar(e.wheel_speed_scale_left, "speed scale left", "%", "max_speed_scale_percent",
             t.max_speed_scale_percent, c.wheel_speed_scale_left_percent),
      scalar(e.wheel_speed_scale_right, "speed scale right", "%", "max_speed_scale_percent",
             t.max_speed_scale_percent, c.wheel_speed_scale_right_percent),
      scalar(e.odometry_speed_scale, "odometry speed scale", "%", "max_speed_scale_percent",
             t.max_speed_scale_percent, c.odometry_speed_scale_percent),
      scalar(e.effective_track, "effective track", "%", "max_effective_track_percent",
             t.max_effective_track_percent, c.effective_track_percent),
      vector(e.p_I_A, "lever arm p_I_A", "mm", "max_lever_arm_mm", t.max_lever_arm_mm, c.p_I_A_mm),
      vector(e.T_I_V_rotation, "T_I_V rotation", "deg", "max_vehicle_rotation_deg",
             t.max_vehicle_rotation_deg, c.T_I_V.rotation_deg),
      vector(e.T_I_V_translation, "T_I_V translation", "mm", "max_vehicle_translation_mm",
             t.max_vehicle_translation_mm, c.T_I_V.translation_mm),
      scalar(e.wheel_time_offset, "wheel clock offset", "ms", "max_wheel_time_offset_ms",
             t.max_wheel_time_offset_ms, c.wheel_time_offset_ms),
      scalar(e.gnss_time_offset, "GNSS clock offset", "ms", "max_gnss_time_offset_ms",
             t.max_gnss_time_offset_ms, c.gnss_time_offset_ms),
      MakeRow("ATE translation RMSE", "m", "max_ate_m", t.max_ate_m),
      MakeRow("ATE rotation RMSE", "deg", "max_ate_deg", t.max_ate_deg),
  };
  Row& ate_m = rows[rows.size() - 2];
  Row& ate_deg = rows[rows.size() - 1];
  ate_m.measured = ate_deg.measured = evaluation.trajectory.has_value();
  if (evaluation.trajectory) {
    ate_m.value = evaluation.trajectory->ate_translation_rmse_m;
    ate_deg.value = evaluation.trajectory->ate_rotation_rmse_deg;
  }
  for (const Row& row : rows) {
    if (row.limit && !(std::isfinite(*row.limit) && *row.limit >= 0.0)) {
      throw Error(std::string("threshold ") + row.threshold +
                  " must be a finite number >= 0, got " + std::to_string(*row.limit));
    }
  }
  return rows;
}

// Shortest text that reads back to the same double; YAML's .nan for NaN.
std::string Number(double value) {
  if (std::isnan(value)) return ".nan";
  if (std::isinf(value)) return value > 0 ? ".inf" : "-.inf";
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

std::string List(const Eigen::Vector3d& v) {
  return "[" + Number(v.x()) + ", " + Number(v.y()) + ", " + Number(v.z()) + "]";
}

std::string PoseYaml(const char* name, const PoseError& error) {
  std::string out = std::string("  ") + name + ":\n";
  out += "    rotation_error_deg: " + Number(error.RotationAngleDeg()) + "\n";
  out += "    rotation_error_axes_deg: " + List(error.rotation_deg) + "\n";
  out += "    translation_error_mm: " + Number(error.TranslationNormMm()) + "\n";
  out += "    translation_error_axes_mm: " + List(error.translation_mm) + "\n";
  return out;
}

// Each block of EstimatedBlocks with its calibration.yaml key.
constexpr std::pair<bool EstimatedBlocks::*, const char*> kBlockKeys[] = {
    {&EstimatedBlocks::T_I_L, "T_I_L"},
    {&EstimatedBlocks::time_offset, "time_offset_lidar_imu_s"},
    {&EstimatedBlocks::wheel_radius_left, "wheel_radius_left_m"},
    {&EstimatedBlocks::wheel_radius_right, "wheel_radius_right_m"},
    {&EstimatedBlocks::track_width, "track_width_m"},
    {&EstimatedBlocks::wheel_speed_scale_left, "wheel_speed_scale_left"},
    {&EstimatedBlocks::wheel_speed_scale_right, "wheel_speed_scale_right"},
    {&EstimatedBlocks::odometry_speed_scale, "odometry_speed_scale"},
    {&EstimatedBlocks::effective_track, "effective_track_m"},
    {&EstimatedBlocks::p_I_A, "p_I_A_m"},
    {&EstimatedBlocks::T_I_V_rotation, "T_I_V rotation"},
    {&EstimatedBlocks::T_I_V_translation, "T_I_V translation"},
    {&EstimatedBlocks::wheel_time_offset, "time_offset_wheel_imu_s"},
    {&EstimatedBlocks::gnss_time_offset, "time_offset_gnss_imu_s"},
};

// The blocks the result did not estimate, by their calibration.yaml keys, comma-separated.
std::string NotEstimated(const EstimatedBlocks& e) {
  std::string out;
  for (const auto& [estimated, key] : kBlockKeys) {
    if (e.*estimated) continue;
    out += (out.empty() ? "\"" : ", \"") + std::string(key) + "\"";
  }
  return out;
}

// A block is estimated when the result states its sigma; a file that states none (hand-written,
// another tool's) says nothing about it, and every block counts as estimated.
EstimatedBlocks EstimatedIn(const io::CalibrationUncertainty& u) {
  EstimatedBlocks e;
  e.T_I_L = u.T_I_L.sigma_rot_deg.has_value() || u.T_I_L.sigma_p_m.has_value();
  e.time_offset = u.time_offset_lidar_imu_s.sigma.has_value();
  e.wheel_radius_left = u.wheel_radius_left_m.sigma.has_value();
  e.wheel_radius_right = u.wheel_radius_right_m.sigma.has_value();
  e.track_width = u.track_width_m.sigma.has_value();
  e.wheel_speed_scale_left = u.wheel_speed_scale_left.sigma.has_value();
  e.wheel_speed_scale_right = u.wheel_speed_scale_right.sigma.has_value();
  e.odometry_speed_scale = u.odometry_speed_scale.sigma.has_value();
  e.effective_track = u.effective_track_m.sigma.has_value();
  e.p_I_A = u.p_I_A_m.sigma.has_value();
  e.T_I_V_rotation = u.T_I_V.sigma_rot_deg.has_value();
  e.T_I_V_translation = u.T_I_V.sigma_p_m.has_value();
  e.wheel_time_offset = u.time_offset_wheel_imu_s.sigma.has_value();
  e.gnss_time_offset = u.time_offset_gnss_imu_s.sigma.has_value();
  const bool any = std::any_of(std::begin(kBlockKeys), std::end(kBlockKeys),
                               [&](const auto& block) { return e.*block.first; });
  return any ? e : EstimatedBlocks();
}

}  // namespace

std::string ThresholdViolation::ToString() const {
  if (std::isnan(value)) return metric + " " + unmeasured + ", but " + threshold + " is given";
  char buffer[160];
  std::snprintf(buffer, sizeof(buffer), "%s %.6g %s > %s %.6g", metric.c_str(), std::abs(value),
                unit.c_str(), threshold.c_str(), limit);
  return buffer;
}

std::vector<ThresholdViolation> ExceededThresholds(const Evaluation& evaluation,
                                                   const Thresholds& thresholds) {
  std::vector<ThresholdViolation> violations;
  for (const Row& row : Rows(evaluation, thresholds)) {
    if (!row.Exceeded()) continue;
    violations.push_back(
        {row.threshold, row.metric, row.unit,
         row.measured ? std::abs(row.value) : std::numeric_limits<double>::quiet_NaN(), *row.limit,
         row.unmeasured});
  }
  return violations;
}

std::string FormatEvaluationTable(const Evaluation& evaluation, const Thresholds& thresholds) {
  char line[256];
  std::snprintf(line, sizeof(line), "%-22s %12s %-4s %-30s %10s  %s\n", "metric", "error", "unit",
                "per axis (x, y, z)", "limit", "verdict");
  std::string out = line;
  for (const Row& row : Rows(evaluation, thresholds)) {
    const std::string value = row.measured            ? FormatFixed(row.value, 4)
                              : std::isnan(row.value) ? std::string("n/a")
                                                      : std::string("not estimated");
    const std::string axes = row.axes && row.measured ? "(" + FormatFixed(row.axes->x(), 3) + ", " +
                                                            FormatFixed(row.axes->y(), 3) + ", " +
                                                            FormatFixed(row.axes->z(), 3) + ")"
                                                      : "";
    const std::string limit = row.limit ? FormatFixed(*row.limit, 4) : "-";
    const char* verdict = !row.limit ? "-" : row.Exceeded() ? "EXCEEDED" : "ok";
    std::snprintf(line, sizeof(line), "%-22s %12s %-4s %-30s %10s  %s\n", row.metric, value.c_str(),
                  row.unit, axes.c_str(), limit.c_str(), verdict);
    out += line;
  }
  if (evaluation.trajectory) {
    const TrajectoryErrors& t = *evaluation.trajectory;
    std::snprintf(line, sizeof(line),
                  "trajectory: %d poses matched (%d exactly, %d unmatched), aligned by yaw %.4f "
                  "deg%s and translation (%.3f, %.3f, %.3f) m\n",
                  t.matched_poses, t.exact_matches, t.unmatched_poses,
                  kRadToDeg * t.alignment.yaw_rad,
                  t.alignment.yaw_from_orientation ? " (from orientations)" : "",
                  t.alignment.translation_m.x(), t.alignment.translation_m.y(),
                  t.alignment.translation_m.z());
    out += line;
  }
  return out;
}

std::string EvaluationYamlText(const Evaluation& evaluation, const Thresholds& thresholds) {
  const CalibrationErrors& c = evaluation.calibration;
  std::string out =
      "# autocal evaluation: result minus ground truth (docs/evaluation.md).\n"
      "calibration:\n";
  out += PoseYaml("T_I_L", c.T_I_L);
  out += "  time_offset_error_ms: " + Number(c.time_offset_ms) + "\n";
  out += "  wheel_radius_left_error_percent: " + Number(c.wheel_radius_left_percent) + "\n";
  out += "  wheel_radius_right_error_percent: " + Number(c.wheel_radius_right_percent) + "\n";
  out += "  track_width_error_percent: " + Number(c.track_width_percent) + "\n";
  out +=
      "  wheel_speed_scale_left_error_percent: " + Number(c.wheel_speed_scale_left_percent) + "\n";
  out += "  wheel_speed_scale_right_error_percent: " + Number(c.wheel_speed_scale_right_percent) +
         "\n";
  out += "  odometry_speed_scale_error_percent: " + Number(c.odometry_speed_scale_percent) + "\n";
  out += "  effective_track_error_percent: " + Number(c.effective_track_percent) + "\n";
  out += "  p_I_A:\n";
  out += "    error_mm: " + Number(c.p_I_A_mm.norm()) + "\n";
  out += "    error_axes_mm: " + List(c.p_I_A_mm) + "\n";
  out += PoseYaml("T_I_V", c.T_I_V);
  out += "  wheel_time_offset_error_ms: " + Number(c.wheel_time_offset_ms) + "\n";
  out += "  gnss_time_offset_error_ms: " + Number(c.gnss_time_offset_ms) + "\n";
  out += "  not_estimated: [" + NotEstimated(evaluation.estimated) + "]\n";
  if (evaluation.trajectory) {
    const TrajectoryErrors& t = *evaluation.trajectory;
    out += "trajectory:\n";
    out += "  file: \"" + evaluation.trajectory_file + "\"\n";
    out += "  matched_poses: " + std::to_string(t.matched_poses) + "\n";
    out += "  exact_matches: " + std::to_string(t.exact_matches) + "\n";
    out += "  unmatched_poses: " + std::to_string(t.unmatched_poses) + "\n";
    out += "  ate_translation_rmse_m: " + Number(t.ate_translation_rmse_m) + "\n";
    out += "  ate_rotation_rmse_deg: " + Number(t.ate_rotation_rmse_deg) + "\n";
    out += "  tilt_rmse_deg: " + Number(t.tilt_rmse_deg) + "\n";
    out += "  max_translation_error_m: " + Number(t.max_translation_error_m) + "\n";
    out += "  max_rotation_error_deg: " + Number(t.max_rotation_error_deg) + "\n";
    out += "  alignment:\n";
    out += "    yaw_deg: " + Number(kRadToDeg * t.alignment.yaw_rad) + "\n";
    out += "    translation_m: " + List(t.alignment.translation_m) + "\n";
    out += std::string("    yaw_from_orientation: ") +
           (t.alignment.yaw_from_orientation ? "true" : "false") + "\n";
  }
  const std::vector<Row> rows = Rows(evaluation, thresholds);
  std::string given;
  std::string previous;
  for (const Row& row : rows) {
    // The radius limit serves two rows; list it once.
    if (!row.limit || previous == row.threshold) continue;
    given += std::string("  ") + row.threshold + ": " + Number(*row.limit) + "\n";
    previous = row.threshold;
  }
  out += given.empty() ? "thresholds: {}\n" : "thresholds:\n" + given;
  const std::vector<ThresholdViolation> violations = ExceededThresholds(evaluation, thresholds);
  out += violations.empty() ? "exceeded: []\n" : "exceeded:\n";
  for (const ThresholdViolation& v : violations) {
    out += "  - {threshold: " + v.threshold + ", metric: \"" + v.metric +
           "\", value: " + Number(v.value) + ", unit: \"" + v.unit +
           "\", limit: " + Number(v.limit) + "}\n";
  }
  out += std::string("passed: ") + (violations.empty() ? "true" : "false") + "\n";
  return out;
}

void WriteEvaluationYaml(const std::string& path, const Evaluation& evaluation,
                         const Thresholds& thresholds) {
  const std::string text = EvaluationYamlText(evaluation, thresholds);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw Error("cannot open '" + path + "' for writing");
  out << text;
  out.close();
  if (!out) throw Error("error while writing '" + path + "'");
}

ResultPaths ResultPaths::For(const std::string& dataset_directory,
                             const std::string& result_directory) {
  const std::filesystem::path dataset(dataset_directory);
  const std::filesystem::path result(result_directory);
  ResultPaths paths;
  paths.truth_calibration = (dataset / "groundtruth" / "calibration.yaml").string();
  paths.truth_trajectory = (dataset / "groundtruth" / "trajectory.csv").string();
  paths.result_calibration = (result / "calibration.yaml").string();
  paths.result_trajectory = (result / "trajectory.tum").string();
  paths.evaluation = (result / "evaluation.yaml").string();
  return paths;
}

Evaluation EvaluateResult(const ResultPaths& paths, const TrajectoryErrorOptions& options) {
  const auto require = [](const std::string& path, const std::string& what) {
    std::error_code error;
    if (!std::filesystem::is_regular_file(path, error))
      throw Error(what + " not found: '" + path + "' does not exist or is not a file");
  };
  require(paths.truth_calibration, "ground-truth calibration");
  require(paths.result_calibration, "result calibration");
  Evaluation evaluation;
  const io::CalibrationFile result = io::ReadCalibrationYaml(paths.result_calibration);
  evaluation.calibration =
      CompareCalibration(result.value, io::ReadCalibrationYaml(paths.truth_calibration).value);
  evaluation.estimated = EstimatedIn(result.uncertainty);
  std::error_code error;
  if (std::filesystem::exists(paths.result_trajectory, error)) {
    require(paths.truth_trajectory, "the result has a trajectory, but the ground-truth trajectory");
    evaluation.trajectory =
        CompareTrajectory(io::ReadTumTrajectory(paths.result_trajectory),
                          io::ReadTrajectoryCsv(paths.truth_trajectory), options);
    evaluation.trajectory_file = paths.result_trajectory;
  }
  return evaluation;
}

}  // namespace evaluation
}  // namespace autocal
