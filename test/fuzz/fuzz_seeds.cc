// Writes the seed corpus of the fuzz targets: small valid files of every format, made by
// autocal's own writers (so they track the formats), into <out>/<target>/.
//   autocal_fuzz_seeds <out>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "autocal/io/calibration_yaml.h"
#include "autocal/io/csv_files.h"
#include "autocal/io/point_cloud_file.h"
#include "autocal/io/sensors_yaml.h"
#include "autocal/io/tum_trajectory.h"

namespace autocal {
namespace fuzz {
namespace {

constexpr int64_t kStartNs = 1'700'000'000'000'000'000;
constexpr int kSamples = 4;

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void WriteAll(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

// The CSV target reads byte 0 as the reader to use, the rest as the file.
void PrefixSelector(const std::string& path, char selector) {
  WriteAll(path, std::string(1, selector) + ReadAll(path));
}

void WriteCsvSeeds(const std::string& dir) {
  sensors::ImuSamples imu(kSamples);
  sensors::WheelSamples wheel(kSamples);
  sensors::GnssFixes gnss(kSamples);
  std::vector<io::LidarSweepRef> lidar(kSamples);
  io::Trajectory trajectory(kSamples);
  for (int i = 0; i < kSamples; ++i) {
    const int64_t t_ns = kStartNs + i * 10'000'000;
    imu[i].t_ns = wheel[i].t_ns = gnss[i].t_ns = lidar[i].t_ns = trajectory[i].t_ns = t_ns;
    imu[i].accel_m_s2 << 0.1 * i, 0.0, 9.81;
    imu[i].gyro_rad_s << 0.0, 0.01, 0.25;
    wheel[i].left_rad_s = wheel[i].right_rad_s = 15.0 + i;
    gnss[i].lat_deg = 48.1 + 1e-6 * i;
    gnss[i].lon_deg = 11.5;
    gnss[i].alt_m = 520.0;
    lidar[i].file = std::to_string(t_ns) + ".ply";
    trajectory[i].T_W_I.p << i, 0.5 * i, 0.0;
  }
  io::WriteImuCsv(dir + "/imu.csv", imu);
  io::WriteWheelCsv(dir + "/wheel.csv", wheel);
  io::WriteGnssCsv(dir + "/gnss.csv", gnss);
  io::WriteLidarCsv(dir + "/lidar.csv", lidar);
  io::WriteTrajectoryCsv(dir + "/trajectory.csv", trajectory);
  PrefixSelector(dir + "/imu.csv", 0);
  PrefixSelector(dir + "/wheel.csv", 1);
  PrefixSelector(dir + "/gnss.csv", 2);
  PrefixSelector(dir + "/lidar.csv", 3);
  PrefixSelector(dir + "/trajectory.csv", 4);
  sensors::WheelSpeedSamples speeds(kSamples);
  sensors::OdometrySamples odometry(kSamples);
  for (int i = 0; i < kSamples; ++i) {
    speeds[i].t_ns = odometry[i].t_ns = wheel[i].t_ns;
    speeds[i].left_m_s = speeds[i].front_left_m_s = 5.0 + 0.1 * i;
    speeds[i].right_m_s = speeds[i].front_right_m_s = 5.2 + 0.1 * i;
    speeds[i].has_front = true;
    odometry[i].speed_m_s = 0.8;
    odometry[i].yaw_rate_rad_s = 0.01 * i;
  }
  io::WriteWheelSpeedCsv(dir + "/wheel_speed.csv", speeds);
  io::WriteOdometryCsv(dir + "/odometry.csv", odometry);
  PrefixSelector(dir + "/wheel_speed.csv", 5);
  PrefixSelector(dir + "/odometry.csv", 6);
}

void WritePointCloudSeeds(const std::string& dir) {
  lidar::PointCloud cloud;
  cloud.points.resize(3, kSamples);
  cloud.intensity.resize(kSamples);
  cloud.time_s.resize(kSamples);
  for (int i = 0; i < kSamples; ++i) {
    cloud.points.col(i) << i, -i, 0.5 * i;
    cloud.intensity[i] = static_cast<float>(10 * i);
    cloud.time_s[i] = 1e-3 * i;
  }
  io::WritePly(dir + "/sweep.ply", cloud);
}

void WriteYamlAndTumSeeds(const std::string& sensors_dir, const std::string& calibration_dir,
                          const std::string& tum_dir) {
  io::WriteSensorsYaml(sensors_dir + "/sensors.yaml", io::SensorsConfig());
  io::CalibrationFile calibration;
  calibration.uncertainty.time_offset_lidar_imu_s.sigma = 1e-3;
  calibration.solver["termination"] = "CONVERGENCE";
  calibration.residuals["lidar"]["rms_m"] = 0.02;
  io::WriteCalibrationYaml(calibration_dir + "/calibration.yaml", calibration);
  io::Trajectory trajectory(kSamples);
  for (int i = 0; i < kSamples; ++i) {
    trajectory[i].t_ns = kStartNs + i * 123'456'789;
    trajectory[i].T_W_I.p << i, 2.0 * i, -0.5;
  }
  io::WriteTumTrajectory(tum_dir + "/trajectory.tum", trajectory);
}

}  // namespace
}  // namespace fuzz
}  // namespace autocal

int main(int argc, char** argv) {
  using namespace autocal::fuzz;
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <corpus directory>\n", argv[0]);
    return 2;
  }
  const std::string out = argv[1];
  for (const char* target :
       {"csv", "ply", "pcd", "sensors_yaml", "problem_yaml", "calibration_yaml", "tum"}) {
    std::filesystem::create_directories(out + "/" + target);
  }
  WriteCsvSeeds(out + "/csv");
  WritePointCloudSeeds(out + "/ply");
  WriteYamlAndTumSeeds(out + "/sensors_yaml", out + "/calibration_yaml", out + "/tum");
  return 0;
}
