// Writes a simulated log as a dataset directory. Kept apart from simulator.cc so that code
// generating logs in memory does not pull in the dataset writer.

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"
#include "autocal/io/csv_files.h"
#include "autocal/io/output_files.h"
#include "autocal/sim/simulator.h"

namespace autocal {
namespace sim {
namespace {

// Sweeps generated together per thread (about 1 MB each).
constexpr int kSweepsPerThread = 8;

std::ostringstream Text() {
  std::ostringstream out;
  out.precision(17);
  return out;
}

// groundtruth/imu_bias.csv: the true biases at every IMU sample.
void WriteImuBias(const ImuLog& imu, const std::string& path) {
  io::ImuBiasTrajectory biases(imu.samples.size());
  for (size_t k = 0; k < imu.samples.size(); ++k) {
    biases[k] = {imu.samples[k].t_ns, imu.gyro_bias[k], imu.accel_bias[k]};
  }
  io::WriteImuBiasCsv(path, biases);
}

// groundtruth/gnss.csv: per fix, the true antenna position in W and whether it is an outlier.
void WriteGnssTruth(const GnssLog& gnss, const std::string& path) {
  std::ostringstream out = Text();
  out << "t_ns,east_m,north_m,up_m,outlier\n";
  for (size_t i = 0; i < gnss.fixes.size(); ++i) {
    const Eigen::Vector3d& p = gnss.true_p_W_A[i];
    out << gnss.fixes[i].t_ns << ',' << p.x() << ',' << p.y() << ',' << p.z() << ','
        << (gnss.is_outlier[i] ? 1 : 0) << '\n';
  }
  io::WriteFileAtomically(path, out.str());
}

// groundtruth/timing.yaml: how each sensor's stamps relate to the IMU clock (the truth of
// the clock offsets, which sensors::Calibration does not hold) and the stamp models used.
void WriteTiming(const SimulationOptions& o, const std::string& path) {
  std::ostringstream out = Text();
  out << "# Simulated sensor clocks: a measurement stamped t by a sensor was taken at IMU time\n"
      << "# t + offset (t_imu = t_sensor + offset), wheel bursts adding their delay on top.\n"
      << "time_offset_lidar_imu_s: " << o.true_calibration.time_offset_lidar_imu_s << '\n'
      << "time_offset_wheel_imu_s: " << o.wheel.time_offset_wheel_imu_s << '\n'
      << "time_offset_gnss_imu_s: " << o.gnss.time_offset_gnss_imu_s << '\n'
      << "imu:\n"
      << "  rate_hz: " << o.imu.noise.update_rate_hz << '\n'
      << "  stamp_jitter_s: " << o.imu.stamp_jitter_s << '\n'
      << "wheel:\n"
      << "  enabled: " << (o.wheel.enabled ? "true" : "false") << '\n'
      << "  rate_hz: " << o.wheel.config.rate_hz << '\n'
      << "  stamp_jitter_s: " << o.wheel.stamp_jitter_s << '\n'
      << "  burst_size: " << o.wheel.burst_size << '\n'
      << "  burst_span_s: " << o.wheel.burst_span_s << '\n'
      << "  drop_probability: " << o.wheel.drop_probability << '\n'
      << "gnss:\n"
      << "  enabled: " << (o.gnss.enabled ? "true" : "false") << '\n'
      << "  rate_hz: " << o.gnss.config.rate_hz << '\n';
  io::WriteFileAtomically(path, out.str());
}

// The wheel log in the form the options name (its file, datasets/README.md "Wheel forms").
void WriteWheelForm(const Simulator& simulator, const WheelLog& log, io::DatasetWriter* writer) {
  switch (simulator.options().wheel.config.form) {
    case sensors::WheelForm::kLinearSpeeds:
      return writer->WriteWheelSpeeds(simulator.WheelSpeedsOf(log));
    case sensors::WheelForm::kSpeedYawRate:
      return writer->WriteOdometry(simulator.OdometryOf(log));
    case sensors::WheelForm::kAngularRates:
      break;
  }
  writer->WriteWheel(log.samples);
}

}  // namespace

// The dataset is written into a staging directory beside `directory` and renamed to it only
// when every file is written (io/output_files.h): a run stopped midway leaves no directory
// that looks like a dataset.
SimulationSummary WriteDataset(const Simulator& simulator, const std::string& final_directory,
                               int num_threads) {
  if (num_threads < 1) {
    throw Error("WriteDataset: num_threads must be at least 1, got " + std::to_string(num_threads));
  }
  io::StagedDirectory staged(final_directory, io::OutputKind::kDataset);
  const std::string& directory = staged.staging();
  io::DatasetWriter writer(directory);
  writer.WriteSensorsConfig(simulator.sensors_config());
  const ImuLog imu = simulator.GenerateImu();
  writer.WriteImu(imu.samples);
  const WheelLog wheel_log = simulator.GenerateWheelLog();
  const sensors::WheelSamples& wheel = wheel_log.samples;
  if (simulator.options().wheel.enabled) WriteWheelForm(simulator, wheel_log, &writer);
  const GnssLog gnss = simulator.GenerateGnss();
  if (simulator.options().gnss.enabled) writer.WriteGnss(gnss.fixes);
  // Sweeps are generated a stretch at a time on every thread (each from its own random
  // stream, so the files do not depend on the count) and written in order.
  int64_t points = 0;
  const int stretch = kSweepsPerThread * num_threads;
  std::vector<lidar::LidarSweep> sweeps;
  for (int first = 0; first < simulator.num_sweeps(); first += stretch) {
    sweeps.assign(static_cast<size_t>(std::min(stretch, simulator.num_sweeps() - first)),
                  lidar::LidarSweep());
    ParallelFor(
        0, static_cast<int64_t>(sweeps.size()), num_threads, [&](int64_t begin, int64_t end, int) {
          for (int64_t i = begin; i < end; ++i) {
            sweeps[static_cast<size_t>(i)] = simulator.GenerateSweep(first + static_cast<int>(i));
          }
        });
    for (const lidar::LidarSweep& sweep : sweeps) {
      points += sweep.cloud.size();
      writer.AddSweep(sweep);
    }
  }
  writer.WriteGroundTruth(imu.truth, simulator.true_calibration());
  writer.Close();
  const std::filesystem::path truth_dir = std::filesystem::path(directory) / "groundtruth";
  WriteImuBias(imu, (truth_dir / "imu_bias.csv").string());
  if (simulator.options().gnss.enabled) WriteGnssTruth(gnss, (truth_dir / "gnss.csv").string());
  WriteTiming(simulator.options(), (truth_dir / "timing.yaml").string());
  staged.Commit();
  return Summarize(simulator, imu, wheel, gnss, simulator.num_sweeps(), points);
}

}  // namespace sim
}  // namespace autocal
