#pragma once

// A dataset directory in autocal's format (datasets/README.md):
//   sensors.yaml, imu.csv, wheel.csv | wheel_speed.csv | odometry.csv, gnss.csv,
//   lidar.csv + lidar/<file>.ply, groundtruth/trajectory.csv, groundtruth/calibration.yaml.
// Every file but imu.csv is optional. The wheel data come in the form sensors.yaml names
// (wheel.form, default angular_rates): only that form's file is read. Readers validate as they go
// and throw autocal::ParseError naming file, line and column (or byte offset) on the first problem.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "autocal/geometry/se3.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/imu_plausibility.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/measurements.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace io {

// Content of sensors.yaml: which sensors exist, their rates and noise, and the nominal
// calibration (the initial guess a calibration starts from).
struct SensorsConfig {
  sensors::ImuConfig imu;
  std::optional<sensors::LidarConfig> lidar;
  std::optional<sensors::WheelConfig> wheel;
  std::optional<sensors::GnssConfig> gnss;
  sensors::Calibration nominal_calibration;
  // Optional sigmas of the nominal calibration (usable as prior widths) and observability
  // flags, as the nominal_calibration section of sensors.yaml states them.
  CalibrationUncertainty nominal_uncertainty;
};

// One ground-truth state: the IMU pose T_W_I and velocity v_W_I at IMU-clock time t_ns.
struct TrajectorySample {
  int64_t t_ns = 0;
  geometry::Pose3d T_W_I;
  Eigen::Vector3d v_W_I = Eigen::Vector3d::Zero();
};
using Trajectory = std::vector<TrajectorySample>;

// A row of groundtruth/imu_bias.csv: the IMU's true biases at one of its samples.
struct ImuBiasSample {
  int64_t t_ns = 0;
  Eigen::Vector3d b_g = Eigen::Vector3d::Zero();  // rad/s
  Eigen::Vector3d b_a = Eigen::Vector3d::Zero();  // m/s^2
};
using ImuBiasTrajectory = std::vector<ImuBiasSample>;

// A row of lidar.csv: the sweep's reference stamp (LiDAR clock) and its PLY file name,
// relative to <dataset>/lidar/.
struct LidarSweepRef {
  int64_t t_ns = 0;
  std::string file;
};

struct Dataset {
  std::string directory;
  SensorsConfig sensors;
  sensors::ImuSamples imu;
  sensors::WheelSamples wheel;              // empty without wheel.csv
  sensors::WheelSpeedSamples wheel_speeds;  // form linear_speeds: wheel_speed.csv
  sensors::OdometrySamples odometry;        // form speed_yaw_rate: odometry.csv
  sensors::GnssFixes gnss;                  // empty without gnss.csv
  std::vector<LidarSweepRef> lidar_sweeps;  // empty without lidar.csv
  Trajectory groundtruth_trajectory;        // empty without groundtruth/trajectory.csv
  ImuBiasTrajectory groundtruth_imu_bias;   // empty without groundtruth/imu_bias.csv
  std::optional<sensors::Calibration> groundtruth_calibration;

  // The form of the wheel data: sensors.yaml's, angular rates without a wheel section.
  sensors::WheelForm wheel_form() const;
  // Rows of the wheel form's file (0 without it).
  size_t wheel_sample_count() const;

  // Sweeps are large, so they are read on demand. Throws ParseError on a missing or
  // malformed file.
  lidar::LidarSweep LoadSweep(size_t index) const;
  // The file LoadSweep(index) reads: directory/lidar/<file> (index < lidar_sweeps.size()).
  std::string SweepPath(size_t index) const;
};

// The part of a log stamped at or before end_ns (each stream on its own clock, as stamped):
// IMU, wheel (every form), GNSS, sweeps and ground truth, whose stamps increase as ReadDataset
// checks; the configuration as it is. For a solve over the first seconds of a log.
Dataset DatasetUntil(const Dataset& dataset, int64_t end_ns);

struct DatasetReadOptions {
  // Unit checks on imu.csv (the gravity they use comes from sensors.yaml).
  ImuPlausibilityOptions imu_checks;
};

// Reads and validates a whole dataset directory (sweeps excepted: their index is checked,
// the files must exist). The wheel form's file is read; when it is missing but the file of
// another form is there, sensors.yaml and the files disagree: a ParseError names both.
Dataset ReadDataset(const std::string& directory);
Dataset ReadDataset(const std::string& directory, const DatasetReadOptions& options);

// Writes a dataset incrementally, so a simulator need not hold all sweeps in memory.
// Creates the directory (and lidar/, groundtruth/) if needed.
class DatasetWriter {
 public:
  explicit DatasetWriter(std::string directory);
  ~DatasetWriter();
  DatasetWriter(const DatasetWriter&) = delete;
  DatasetWriter& operator=(const DatasetWriter&) = delete;

  // Throws autocal::Error, naming the field, when ReadSensorsYaml would refuse the file.
  void WriteSensorsConfig(const SensorsConfig& config);
  void WriteImu(const sensors::ImuSamples& samples);
  void WriteWheel(const sensors::WheelSamples& samples);
  void WriteWheelSpeeds(const sensors::WheelSpeedSamples& samples);
  void WriteOdometry(const sensors::OdometrySamples& samples);
  void WriteGnss(const sensors::GnssFixes& fixes);
  // Writes lidar/<t_ns>.ply and appends a row to lidar.csv.
  void AddSweep(const lidar::LidarSweep& sweep);
  void WriteGroundTruth(const Trajectory& trajectory, const sensors::Calibration& calibration);
  // Flushes and closes every file; throws autocal::Error on I/O failure. The destructor
  // closes too but cannot report failures, so call Close() to know the data is on disk.
  void Close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace io
}  // namespace autocal
