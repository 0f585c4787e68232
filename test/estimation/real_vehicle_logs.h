#pragma once

// The shared real robot logs (../shared/data/ros1_bags) imported into a test's output
// directory and read as the offset and mount initializers take them: IMU samples, the
// odometry's speed and yaw rate as scalar series, and the GNSS fixes when the log has them.

#include <filesystem>
#include <string>

#include "autocal/estimation/clock_offsets.h"
#include "autocal/import/import_bag.h"
#include "autocal/io/csv_files.h"
#include "autocal/sensors/measurements.h"
#include "io/csv_reader.h"
#include "support/test_paths.h"

namespace autocal {
namespace test {

struct VehicleLog {
  sensors::ImuSamples imu;
  estimation::ScalarSeries speed_m_s;
  estimation::ScalarSeries yaw_rate_rad_s;
  sensors::GnssFixes gnss;
};

inline std::filesystem::path RealBag(const std::string& name) {
  return SharedDataDir("ros1_bags") / name;
}

// Imports `bag` below the test's output directory and reads its streams.
inline VehicleLog ImportVehicleLog(const std::filesystem::path& bag) {
  const std::filesystem::path dir = OutputDir(bag.stem().string()) / "dataset";
  std::filesystem::remove_all(dir);
  import::ImportOptions options;
  options.input = bag.string();
  options.output = dir.string();
  import::ImportBag(options);
  VehicleLog log;
  log.imu = io::ReadImuCsv((dir / "imu.csv").string());
  io::internal::CsvReader odometry((dir / "odometry.csv").string(),
                                   {"t_ns", "speed_m_s", "yaw_rate_rad_s"});
  while (odometry.Next()) {
    const int64_t t_ns = odometry.Timestamp();
    log.speed_m_s.push_back({t_ns, odometry.Double(1)});
    log.yaw_rate_rad_s.push_back({t_ns, odometry.Double(2)});
  }
  if (std::filesystem::exists(dir / "gnss.csv"))
    log.gnss = io::ReadGnssCsv((dir / "gnss.csv").string());
  return log;
}

}  // namespace test
}  // namespace autocal
