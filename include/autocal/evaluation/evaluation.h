#pragma once

// Evaluation of a calibration result against the ground truth of a dataset: the errors of
// every calibration block and the trajectory ATE, checked against thresholds and reported as
// a text table and as evaluation.yaml (docs/evaluation.md).

#include <optional>
#include <string>
#include <vector>

#include "autocal/evaluation/calibration_errors.h"
#include "autocal/evaluation/trajectory_errors.h"

namespace autocal {
namespace evaluation {

// Which blocks the result estimated: those its calibration.yaml gives a sigma (a block held
// fixed, or of a sensor or wheel form the problem did not use, has none; a file without any
// sigma counts every block as estimated). The error of a block
// not estimated is the nominal value's, which says nothing about the calibration: the table
// shows it as "not estimated" and a limit on it never passes.
struct EstimatedBlocks {
  bool T_I_L = true;
  bool time_offset = true;
  bool wheel_radius_left = true;
  bool wheel_radius_right = true;
  bool track_width = true;
  bool wheel_speed_scale_left = true;
  bool wheel_speed_scale_right = true;
  bool odometry_speed_scale = true;
  bool effective_track = true;
  bool p_I_A = true;
  bool T_I_V_rotation = true;
  bool T_I_V_translation = true;
  bool wheel_time_offset = true;
  bool gnss_time_offset = true;
};

struct Evaluation {
  CalibrationErrors calibration;
  EstimatedBlocks estimated;
  // Present when an estimated trajectory was evaluated, with the file it was read from.
  std::optional<TrajectoryErrors> trajectory;
  std::string trajectory_file;
};

// Limits on the magnitude of each error. Every limit is optional; an unset limit is not
// checked (the default: nothing is checked). Names match autocal_evaluate's flags.
struct Thresholds {
  std::optional<double> max_rotation_deg;             // T_I_L rotation angle |δ|
  std::optional<double> max_translation_mm;           // T_I_L |p_est − p_true|
  std::optional<double> max_time_offset_ms;           // |offset_est − offset_true|
  std::optional<double> max_radius_percent;           // each wheel radius, |relative error|
  std::optional<double> max_track_width_percent;      // |relative error|
  std::optional<double> max_lever_arm_mm;             // |p_I_A est − true|
  std::optional<double> max_vehicle_rotation_deg;     // T_I_V rotation angle
  std::optional<double> max_vehicle_translation_mm;   // T_I_V translation
  std::optional<double> max_speed_scale_percent;      // each speed scale and k_v
  std::optional<double> max_effective_track_percent;  // b_eff
  std::optional<double> max_wheel_time_offset_ms;     // the wheels' clock
  std::optional<double> max_gnss_time_offset_ms;      // the receiver's clock
  std::optional<double> max_ate_m;                    // ATE translation RMSE
  std::optional<double> max_ate_deg;                  // ATE rotation RMSE
};

// One error above its limit. value is NaN when the metric could not be measured (an ATE limit
// without an evaluated trajectory, a block the result did not estimate): an unmeasured metric
// never passes.
struct ThresholdViolation {
  std::string threshold;  // "max_rotation_deg"
  std::string metric;     // "T_I_L rotation"
  std::string unit;       // "deg"
  double value = 0.0;
  double limit = 0.0;
  std::string unmeasured = "not measured";  // why value is NaN

  // "T_I_L rotation 0.61 deg > max_rotation_deg 0.5".
  std::string ToString() const;
};

// Every metric whose magnitude exceeds its given limit, in table order. Throws autocal::Error
// on a negative or non-finite limit.
std::vector<ThresholdViolation> ExceededThresholds(const Evaluation& evaluation,
                                                   const Thresholds& thresholds);

// One line per metric: name, error (magnitude, and per axis for vectors), unit, limit and
// verdict ("ok", "EXCEEDED", "-" without a limit).
std::string FormatEvaluationTable(const Evaluation& evaluation, const Thresholds& thresholds);

// The evaluation.yaml document (schema in docs/evaluation.md): every error, the thresholds
// given, the violations and `passed`.
std::string EvaluationYamlText(const Evaluation& evaluation, const Thresholds& thresholds);
// Throws autocal::Error on I/O failure.
void WriteEvaluationYaml(const std::string& path, const Evaluation& evaluation,
                         const Thresholds& thresholds);

// The files an evaluation of a result directory reads.
struct ResultPaths {
  std::string truth_calibration;   // <dataset>/groundtruth/calibration.yaml (required)
  std::string truth_trajectory;    // <dataset>/groundtruth/trajectory.csv
  std::string result_calibration;  // <result>/calibration.yaml (required)
  std::string result_trajectory;   // <result>/trajectory.tum (optional)
  std::string evaluation;          // <result>/evaluation.yaml (written)

  static ResultPaths For(const std::string& dataset_directory, const std::string& result_directory);
};

// Reads the truth and the result and compares them; the trajectory is evaluated when
// result_trajectory exists. Throws autocal::Error (ParseError for malformed files) when a
// required file is missing, or when the result has a trajectory and the dataset has none.
Evaluation EvaluateResult(const ResultPaths& paths, const TrajectoryErrorOptions& options = {});

}  // namespace evaluation
}  // namespace autocal
