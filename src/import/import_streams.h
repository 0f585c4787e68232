#pragma once

// The message-by-message part of an import: decodes each message of a selected topic and
// turns it into dataset rows (docs/import.md, "Message mapping"). Sweeps go straight to
// the DatasetWriter; the small streams are kept and written, sorted by stamp, by Finish().
// Private to src/import.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "autocal/import/import_bag.h"
#include "autocal/io/dataset.h"
#include "import/bag_reader.h"
#include "import/static_transforms.h"
#include "import/topic_selection.h"

namespace autocal {
namespace import {

// A row of odometry.csv: vehicle speed and yaw rate (datasets/README.md).
using OdometrySample = sensors::OdometrySample;

class StreamImporter {
 public:
  StreamImporter(const ImportOptions& options, const TopicSelection& selection,
                 io::DatasetWriter* writer, ImportSummary* summary);

  // Decodes `message` when its connection feeds a stream; ignores it otherwise.
  void Add(const std::string& bag_path, const BagMessage& message);
  // Writes imu.csv, wheel.csv, gnss.csv, odometry.csv and sensors.yaml into `directory`.
  void Finish(const std::string& directory);

 private:
  int64_t Stamp(int64_t header_ns, int64_t log_ns);
  void AddImu(MessageCursor* cursor, int64_t log_ns);
  void AddCloud(MessageCursor* cursor, int64_t log_ns);
  void AddJointState(MessageCursor* cursor, int64_t log_ns);
  // Wheel rates from a JointState's angles: the difference with the previous message's angles
  // is the rate midway between them (exact for a steady acceleration), stamped there
  // (*midway_ns; at the later message it would lag by half the interval). Every call with an
  // advancing stamp makes `angles_rad` the next reference; nullopt for the first, and for a
  // stamp at or before the reference's (*unordered).
  std::optional<Eigen::Vector2d> RatesFromAngles(int64_t t_ns, const Eigen::Vector2d& angles_rad,
                                                 int64_t* midway_ns, bool* unordered);
  void AddFix(MessageCursor* cursor, int64_t log_ns);
  void AddOdometry(MessageCursor* cursor, int64_t log_ns);
  // Indices of the left and right wheel joints among `names` (docs/import.md rule).
  std::pair<int, int> WheelJoints(const std::vector<std::string>& names);
  // The rates sensors.yaml states (rates_). An IMU without one is an error; another stream
  // without one (a single sample, or a rate outside what sensors.yaml may state) is left out
  // with a warning, its lidar.written set to 0 for the LiDAR.
  void MeasureRates();
  // Measured rates and the nominal calibration; the IMU noise stays at its defaults.
  io::SensorsConfig MakeSensorsConfig();
  sensors::Calibration NominalCalibration();
  void Warn(const std::string& line) { summary_->warnings.push_back(line); }

  const ImportOptions& options_;
  const TopicSelection& selection_;
  io::DatasetWriter* writer_;
  ImportSummary* summary_;
  MessageContext context_;

  sensors::ImuSamples imu_;
  sensors::WheelSamples wheel_;
  sensors::GnssFixes gnss_;
  std::vector<OdometrySample> odometry_;
  StaticTransforms transforms_;
  struct {
    double imu = 0.0, lidar = 0.0, wheel = 0.0, odometry = 0.0, gnss = 0.0;  // Hz
  } rates_;
  std::string imu_frame_, lidar_frame_, gnss_frame_;

  // LiDAR
  int64_t last_sweep_ns_ = 0;
  uint32_t lidar_rows_ = 0;
  std::vector<int64_t> sweep_stamps_;
  bool warned_no_point_time_ = false;
  // Wheels: joint names of the last message and their indices; the previous positions for
  // a JointState without velocities.
  std::vector<std::string> joint_names_;
  std::pair<int, int> joint_indices_{-1, -1};
  bool has_previous_angles_ = false;
  int64_t previous_angles_ns_ = 0;
  Eigen::Vector2d previous_angles_rad_ = Eigen::Vector2d::Zero();

  // Counts for the warnings.
  int64_t zero_stamps_ = 0;
  int64_t unordered_sweeps_ = 0;
  int64_t empty_sweeps_ = 0;
  int64_t dropped_points_ = 0;
  int64_t no_fix_ = 0;
  int64_t non_finite_fix_ = 0;  // NaN or infinite latitude, longitude or altitude
  int64_t defaulted_gnss_sigma_ = 0;
  int64_t joint_states_without_wheels_ = 0;
  int64_t unordered_joint_positions_ = 0;  // positions-only messages not after the previous one
  int64_t non_finite_joint_states_ = 0;    // no finite velocities, nor finite angles to use
  int64_t non_finite_imu_ = 0;             // NaN or infinite rate or specific force
  int64_t non_finite_odometry_ = 0;        // NaN or infinite speed or yaw rate
};

}  // namespace import
}  // namespace autocal
