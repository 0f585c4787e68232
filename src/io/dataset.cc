#include "autocal/io/dataset.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/csv_files.h"
#include "autocal/io/point_cloud_file.h"
#include "autocal/io/sensors_yaml.h"
#include "io/csv_format.h"

namespace autocal {
namespace io {
namespace {

namespace fs = std::filesystem;

std::string Join(const std::string& directory, const std::string& name) {
  return (fs::path(directory) / name).string();
}

bool IsFile(const std::string& path) {
  std::error_code error;
  return fs::is_regular_file(path, error);
}

// Reads the wheel data of the form sensors.yaml names. A missing file of that form is no wheel
// data, unless the file of another form is there: then sensors.yaml and the files disagree.
void ReadWheelData(const std::string& directory, Dataset* dataset) {
  const sensors::WheelForm form = dataset->wheel_form();
  const std::string path = Join(directory, sensors::WheelFormFile(form));
  if (!IsFile(path)) {
    for (sensors::WheelForm other :
         {sensors::WheelForm::kAngularRates, sensors::WheelForm::kLinearSpeeds,
          sensors::WheelForm::kSpeedYawRate}) {
      const std::string other_path = Join(directory, sensors::WheelFormFile(other));
      if (other == form || !IsFile(other_path)) continue;
      SourceLocation location;
      location.file = Join(directory, "sensors.yaml");
      throw ParseError(
          location,
          std::string("the wheel form is ") + sensors::WheelFormName(form) +
              (dataset->sensors.wheel ? "" : " (no wheel section: the default)") +
              ", which reads " + sensors::WheelFormFile(form) + ", but the dataset has no " +
              sensors::WheelFormFile(form) + " and has " + sensors::WheelFormFile(other) +
              ": set wheel: {form: " + sensors::WheelFormName(other) + "} in sensors.yaml");
    }
    return;
  }
  switch (form) {
    case sensors::WheelForm::kAngularRates:
      dataset->wheel = ReadWheelCsv(path);
      return;
    case sensors::WheelForm::kLinearSpeeds:
      dataset->wheel_speeds = ReadWheelSpeedCsv(path);
      return;
    case sensors::WheelForm::kSpeedYawRate:
      break;
  }
  dataset->odometry = ReadOdometryCsv(path);
}

// The samples of a series (stamps increasing) stamped at or before end_ns.
template <typename Stamped>
std::vector<Stamped> StampedUntil(const std::vector<Stamped>& series, int64_t end_ns) {
  const auto end =
      std::upper_bound(series.begin(), series.end(), end_ns,
                       [](int64_t t_ns, const Stamped& sample) { return t_ns < sample.t_ns; });
  return std::vector<Stamped>(series.begin(), end);
}

}  // namespace

sensors::WheelForm Dataset::wheel_form() const {
  return sensors.wheel ? sensors.wheel->form : sensors::WheelForm::kAngularRates;
}

size_t Dataset::wheel_sample_count() const {
  switch (wheel_form()) {
    case sensors::WheelForm::kAngularRates:
      return wheel.size();
    case sensors::WheelForm::kLinearSpeeds:
      return wheel_speeds.size();
    case sensors::WheelForm::kSpeedYawRate:
      break;
  }
  return odometry.size();
}

Dataset DatasetUntil(const Dataset& dataset, int64_t end_ns) {
  Dataset out;
  out.directory = dataset.directory;
  out.sensors = dataset.sensors;
  out.imu = StampedUntil(dataset.imu, end_ns);
  out.wheel = StampedUntil(dataset.wheel, end_ns);
  out.wheel_speeds = StampedUntil(dataset.wheel_speeds, end_ns);
  out.odometry = StampedUntil(dataset.odometry, end_ns);
  out.gnss = StampedUntil(dataset.gnss, end_ns);
  out.lidar_sweeps = StampedUntil(dataset.lidar_sweeps, end_ns);
  out.groundtruth_trajectory = StampedUntil(dataset.groundtruth_trajectory, end_ns);
  out.groundtruth_imu_bias = StampedUntil(dataset.groundtruth_imu_bias, end_ns);
  out.groundtruth_calibration = dataset.groundtruth_calibration;
  return out;
}

std::string Dataset::SweepPath(size_t index) const {
  return (fs::path(directory) / "lidar" / lidar_sweeps.at(index).file).string();
}

lidar::LidarSweep Dataset::LoadSweep(size_t index) const {
  if (index >= lidar_sweeps.size()) {
    throw Error("LoadSweep(" + std::to_string(index) + "): the dataset '" + directory + "' has " +
                std::to_string(lidar_sweeps.size()) + " sweeps");
  }
  lidar::LidarSweep sweep;
  sweep.t_ns = lidar_sweeps[index].t_ns;
  const std::string path = SweepPath(index);
  if (!IsFile(path)) {
    SourceLocation location;
    location.file = path;
    throw ParseError(location, "sweep file not found (listed in lidar.csv)");
  }
  sweep.cloud = ReadPointCloudFile(path);
  return sweep;
}

Dataset ReadDataset(const std::string& directory) {
  return ReadDataset(directory, DatasetReadOptions());
}

Dataset ReadDataset(const std::string& directory, const DatasetReadOptions& options) {
  std::error_code error;
  if (!fs::is_directory(directory, error)) {
    throw Error("dataset directory '" + directory + "' does not exist or is not a directory");
  }
  Dataset dataset;
  dataset.directory = directory;
  const std::string sensors_path = Join(directory, "sensors.yaml");
  if (IsFile(sensors_path)) dataset.sensors = ReadSensorsYaml(sensors_path);

  const std::string imu_path = Join(directory, "imu.csv");
  if (!IsFile(imu_path)) {
    SourceLocation location;
    location.file = imu_path;
    throw ParseError(location,
                     "missing file: every dataset needs imu.csv (t_ns,gx,gy,gz,ax,ay,az)");
  }
  ImuPlausibilityOptions imu_checks = options.imu_checks;
  imu_checks.gravity_m_s2 = dataset.sensors.imu.gravity_m_s2;
  imu_checks.gyroscope_noise_density = dataset.sensors.imu.noise.gyroscope_noise_density;
  imu_checks.update_rate_hz = dataset.sensors.imu.noise.update_rate_hz;
  dataset.imu = ReadImuCsv(imu_path, imu_checks);

  ReadWheelData(directory, &dataset);
  const std::string gnss_path = Join(directory, "gnss.csv");
  if (IsFile(gnss_path)) dataset.gnss = ReadGnssCsv(gnss_path);
  const std::string lidar_path = Join(directory, "lidar.csv");
  if (IsFile(lidar_path)) dataset.lidar_sweeps = ReadLidarCsv(lidar_path, Join(directory, "lidar"));

  const std::string trajectory_path = Join(directory, "groundtruth/trajectory.csv");
  if (IsFile(trajectory_path)) dataset.groundtruth_trajectory = ReadTrajectoryCsv(trajectory_path);
  const std::string bias_path = Join(directory, "groundtruth/imu_bias.csv");
  if (IsFile(bias_path)) dataset.groundtruth_imu_bias = ReadImuBiasCsv(bias_path);
  const std::string calibration_path = Join(directory, "groundtruth/calibration.yaml");
  if (IsFile(calibration_path))
    dataset.groundtruth_calibration = ReadCalibrationYaml(calibration_path).value;
  return dataset;
}

// ---- DatasetWriter ----

struct DatasetWriter::Impl {
  std::string directory;
  std::ofstream lidar_csv;
  bool has_sweep = false;
  int64_t last_sweep_ns = 0;
  bool closed = false;

  void CheckOpen() const {
    if (closed) throw Error("DatasetWriter for '" + directory + "' is already closed");
  }
};

DatasetWriter::DatasetWriter(std::string directory) : impl_(std::make_unique<Impl>()) {
  impl_->directory = std::move(directory);
  for (const char* sub : {"", "lidar", "groundtruth"}) {
    std::error_code error;
    fs::create_directories(fs::path(impl_->directory) / sub, error);
    if (error) {
      throw Error("cannot create '" + (fs::path(impl_->directory) / sub).string() +
                  "': " + error.message());
    }
  }
}

DatasetWriter::~DatasetWriter() {
  try {
    Close();
  } catch (const Error&) {
    // A destructor cannot report; Close() is the documented way to learn about failures.
  }
}

void DatasetWriter::WriteSensorsConfig(const SensorsConfig& config) {
  impl_->CheckOpen();
  const std::string path = Join(impl_->directory, "sensors.yaml");
  // A dataset its own reader refuses is not written: the reader's ranges are the contract. The
  // text is checked beside the file and only then takes its place, so a refused configuration
  // leaves a sensors.yaml written before as it was.
  const std::string staged = path + ".new";
  WriteSensorsYaml(staged, config);
  std::error_code error;
  try {
    ReadSensorsYaml(staged);
  } catch (const Error& e) {
    std::filesystem::remove(staged, error);
    throw Error(std::string("the sensors' configuration is outside what sensors.yaml may state: ") +
                e.what());
  }
  std::filesystem::rename(staged, path, error);
  if (error) {
    std::filesystem::remove(staged, error);
    throw Error("cannot write " + path + ": " + error.message());
  }
}

void DatasetWriter::WriteImu(const sensors::ImuSamples& samples) {
  impl_->CheckOpen();
  WriteImuCsv(Join(impl_->directory, "imu.csv"), samples);
}

void DatasetWriter::WriteWheel(const sensors::WheelSamples& samples) {
  impl_->CheckOpen();
  WriteWheelCsv(Join(impl_->directory, "wheel.csv"), samples);
}

void DatasetWriter::WriteWheelSpeeds(const sensors::WheelSpeedSamples& samples) {
  impl_->CheckOpen();
  WriteWheelSpeedCsv(Join(impl_->directory, "wheel_speed.csv"), samples);
}

void DatasetWriter::WriteOdometry(const sensors::OdometrySamples& samples) {
  impl_->CheckOpen();
  WriteOdometryCsv(Join(impl_->directory, "odometry.csv"), samples);
}

void DatasetWriter::WriteGnss(const sensors::GnssFixes& fixes) {
  impl_->CheckOpen();
  WriteGnssCsv(Join(impl_->directory, "gnss.csv"), fixes);
}

void DatasetWriter::AddSweep(const lidar::LidarSweep& sweep) {
  impl_->CheckOpen();
  if (impl_->has_sweep && sweep.t_ns <= impl_->last_sweep_ns) {
    throw Error("DatasetWriter::AddSweep: sweep stamp " + std::to_string(sweep.t_ns) +
                " ns does not follow the previous one (" + std::to_string(impl_->last_sweep_ns) +
                " ns)");
  }
  const std::string lidar_csv_path = Join(impl_->directory, "lidar.csv");
  if (!impl_->has_sweep) {
    impl_->lidar_csv.open(lidar_csv_path, std::ios::binary | std::ios::trunc);
    if (!impl_->lidar_csv)
      throw Error("cannot open '" + lidar_csv_path + "' for writing: " + std::strerror(errno));
    impl_->lidar_csv << internal::HeaderLine(internal::LidarColumns());
  }
  LidarSweepRef ref;
  ref.t_ns = sweep.t_ns;
  ref.file = std::to_string(sweep.t_ns) + ".ply";
  WritePly((fs::path(impl_->directory) / "lidar" / ref.file).string(), sweep.cloud);
  impl_->lidar_csv << internal::LidarRow(ref);
  if (!impl_->lidar_csv) throw Error("error while writing '" + lidar_csv_path + "'");
  impl_->has_sweep = true;
  impl_->last_sweep_ns = sweep.t_ns;
}

void DatasetWriter::WriteGroundTruth(const Trajectory& trajectory,
                                     const sensors::Calibration& calibration) {
  impl_->CheckOpen();
  WriteTrajectoryCsv(Join(impl_->directory, "groundtruth/trajectory.csv"), trajectory);
  CalibrationFile file;
  file.value = calibration;
  WriteCalibrationYaml(Join(impl_->directory, "groundtruth/calibration.yaml"), file);
}

void DatasetWriter::Close() {
  if (impl_->closed) return;
  impl_->closed = true;
  if (impl_->lidar_csv.is_open()) {
    impl_->lidar_csv.close();
    if (!impl_->lidar_csv)
      throw Error("error while closing '" + Join(impl_->directory, "lidar.csv") + "'");
  }
}

}  // namespace io
}  // namespace autocal
