#pragma once

// The calibration file schema (datasets/README.md, "calibration.yaml"), shared by the
// nominal calibration in sensors.yaml, the simulator's ground truth and the results of a
// calibration run:
//
//   T_I_L: {q_xyzw: [x, y, z, w], p_m: [x, y, z],
//           sigma_rot_deg: [x, y, z], sigma_p_m: [x, y, z], observable: true}
//   time_offset_lidar_imu_s: {value: 0.012, sigma: 0.0004, observable: true}
//   wheel_radius_left_m: {value: 0.33, sigma: 0.001}
//   wheel_radius_right_m: {value: 0.33}
//   track_width_m: {value: 1.6}
//   p_I_A_m: {value: [x, y, z], sigma: [x, y, z], observable: [true, true, false]}
//   T_I_V: {q_xyzw: [...], p_m: [...]}
//   wheel_speed_scale_left: {value: 1.0}            # wheels as linear speeds
//   wheel_speed_scale_right: {value: 1.0}
//   odometry_speed_scale: {value: 0.97}             # wheels as speed and yaw rate
//   effective_track_m: {value: 0.9}
//   time_offset_wheel_imu_s: {value: -0.2, sigma: 0.002, observable: true}
//   time_offset_gnss_imu_s: {value: 0.15, sigma: 0.01, observable: true}
//   solver: {key: value, ...}                       # free-form solver summary
//   residuals: {lidar: {rms: 0.02, ...}, imu: {...}} # statistics per sensor
//
// A file written by WriteCalibrationYaml states that it is whole: its first key is
// `format: autocal_calibration_1` and its last line the comment `# end of autocal calibration`.
// A file with that format key must end with that line and hold the seven blocks of every rig
// (T_I_L to T_I_V), so that a file cut while it was written is refused (ParseError) instead of
// read with defaults; the four blocks of the other wheel forms (speed scales, odometry speed
// scale, effective track) and the wheel and GNSS time offsets are written always and optional
// on reading, so results written before they existed still read.
// In a file without the format key (hand-written, or the nominal_calibration section of
// sensors.yaml) every block is optional (a missing block keeps the sensors::Calibration
// default); sigma and observable are optional inside a block. A scalar block may be written as a
// bare number and p_I_A_m as a bare [x, y, z]. Unknown keys, wrong types, non-finite
// numbers and quaternions whose norm is off 1 by more than 1e-3 are ParseErrors with
// file, line and column.

#include <Eigen/Core>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "autocal/sensors/calibration.h"

namespace autocal {
namespace io {

// Uncertainty of a pose block T_I_X: rotation sigma about the block's own axes (the right
// perturbation of README "rotation perturbation") in degrees, translation sigma in metres.
// observable is empty, one flag for the whole block, or six flags (rotation x y z,
// translation x y z).
struct PoseBlockInfo {
  std::optional<Eigen::Vector3d> sigma_rot_deg;
  std::optional<Eigen::Vector3d> sigma_p_m;
  std::vector<bool> observable;
};

// observable is empty, one flag for the whole block, or one per axis.
struct VectorBlockInfo {
  std::optional<Eigen::Vector3d> sigma;
  std::vector<bool> observable;
};

struct ScalarBlockInfo {
  std::optional<double> sigma;
  std::optional<bool> observable;
};

struct CalibrationUncertainty {
  PoseBlockInfo T_I_L;
  ScalarBlockInfo time_offset_lidar_imu_s;
  ScalarBlockInfo wheel_radius_left_m;
  ScalarBlockInfo wheel_radius_right_m;
  ScalarBlockInfo track_width_m;
  VectorBlockInfo p_I_A_m;
  PoseBlockInfo T_I_V;
  ScalarBlockInfo wheel_speed_scale_left;
  ScalarBlockInfo wheel_speed_scale_right;
  ScalarBlockInfo odometry_speed_scale;
  ScalarBlockInfo effective_track_m;
  ScalarBlockInfo time_offset_wheel_imu_s;
  ScalarBlockInfo time_offset_gnss_imu_s;
};

struct CalibrationFile {
  sensors::Calibration value;
  CalibrationUncertainty uncertainty;
  // Free-form solver summary, e.g. {"termination": "CONVERGENCE", "iterations": "14"}.
  // Values are kept as the text the file holds.
  std::map<std::string, std::string> solver;
  // Residual statistics per sensor, e.g. residuals["lidar"]["rms_m"] = 0.021.
  std::map<std::string, std::map<std::string, double>> residuals;
};

// Reads a calibration file. Throws ParseError (file, line, column) on malformed content
// and autocal::Error when the file cannot be read.
CalibrationFile ReadCalibrationYaml(const std::string& path);

// Writes `calibration` so that ReadCalibrationYaml returns exactly the same values
// (shortest round-trip decimal for every double), with the format key and end marker, to a
// temporary file renamed into place (io/output_files.h). Throws autocal::Error on I/O failure
// or a non-finite value.
void WriteCalibrationYaml(const std::string& path, const CalibrationFile& calibration);

// The same schema as text, for embedding (sensors.yaml's nominal_calibration section).
// `indent` spaces precede every line.
std::string CalibrationYamlText(const CalibrationFile& calibration, int indent = 0);

}  // namespace io
}  // namespace autocal
