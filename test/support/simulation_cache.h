#pragma once

// Simulated drives made once per test program and build, then loaded.
//
// ctest runs every test in its own process (gtest_discover_tests), so a fixture that
// simulates its drive in SetUpTestSuite simulates it again for each test. The functions here
// simulate on the first call and keep the result below the program's output directory:
//
//   <AUTOCAL_TEST_OUTPUT_DIR>/fixture_cache/<build stamp>/<options key>-<kind>/
//
// The build stamp (size and modification time of the running test program) changes with
// every relink, so a changed simulator or test never reads an old drive; entries of other
// stamps are removed when a new entry is made. The options key hashes every field of
// sim::SimulationOptions. An entry is written into a private temporary directory and renamed
// into place whole, so processes running in parallel never see half an entry (when two make
// the same entry, the first rename wins and the other's copy is dropped).
//
// What is loaded equals what is simulated bit for bit: CachedSimulatedLog stores the raw
// bytes of every number, CachedDataset stores the dataset files sim::WriteDataset wrote.

#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <istream>
#include <string>
#include <system_error>
#include <type_traits>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/sim/simulator.h"

namespace autocal {
namespace test {
namespace simulation_cache {

// Appends the bytes of values; with VisitFields below it serializes a whole log.
class Writer {
 public:
  template <class T>
  void operator()(T& value) {
    Put(value);
  }
  const std::string& bytes() const { return bytes_; }

 private:
  void Raw(const void* data, size_t size) { bytes_.append(static_cast<const char*>(data), size); }
  template <class T>
  std::enable_if_t<std::is_arithmetic_v<T> || std::is_enum_v<T>> Put(T& value) {
    Raw(&value, sizeof(value));
  }
  void Put(std::string& text) {
    uint64_t size = text.size();
    Put(size);
    Raw(text.data(), text.size());
  }
  template <class S, int R, int C, int O, int MR, int MC>
  void Put(Eigen::Matrix<S, R, C, O, MR, MC>& m) {
    int64_t rows = m.rows(), cols = m.cols();
    Put(rows);
    Put(cols);
    Raw(m.data(), sizeof(S) * m.size());
  }
  void Put(Eigen::Quaterniond& q) { Put(q.coeffs()); }
  void Put(std::vector<bool>& flags) {
    uint64_t size = flags.size();
    Put(size);
    for (bool flag : flags) Put(flag);
  }
  template <class A, class B>
  void Put(std::pair<A, B>& pair) {
    (*this)(pair.first);
    (*this)(pair.second);
  }
  template <class T>
  void Put(std::vector<T>& items) {
    uint64_t size = items.size();
    Put(size);
    for (T& item : items) (*this)(item);
  }
  template <class T>
  auto Put(T& value) -> decltype(VisitFields(*this, value)) {
    VisitFields(*this, value);
  }

  std::string bytes_;
};

// Reads what Writer wrote, in the same order; throws autocal::Error when the bytes end early
// or a fixed-size matrix has another size.
// Streams from `in`, which holds `size` bytes (no copy of the whole entry in memory).
class Reader {
 public:
  Reader(std::istream& in, uint64_t size) : in_(in), size_(size) {}
  template <class T>
  void operator()(T& value) {
    Get(value);
  }
  bool at_end() const { return offset_ == size_; }

 private:
  uint64_t Remaining() const { return size_ - offset_; }
  void Raw(void* data, size_t size) {
    if (size > Remaining() || !in_.read(static_cast<char*>(data), size)) {
      throw Error("simulation cache: entry ends early");
    }
    offset_ += size;
  }
  template <class T>
  std::enable_if_t<std::is_arithmetic_v<T> || std::is_enum_v<T>> Get(T& value) {
    Raw(&value, sizeof(value));
  }
  uint64_t Size() {
    uint64_t size = 0;
    Get(size);
    if (size > Remaining()) throw Error("simulation cache: bad length");
    return size;
  }
  void Get(std::string& text) {
    text.resize(Size());
    Raw(text.data(), text.size());
  }
  template <class S, int R, int C, int O, int MR, int MC>
  void Get(Eigen::Matrix<S, R, C, O, MR, MC>& m) {
    int64_t rows = 0, cols = 0;
    Get(rows);
    Get(cols);
    if ((R != Eigen::Dynamic && rows != R) || (C != Eigen::Dynamic && cols != C) || rows < 0 ||
        cols < 0 || (cols > 0 && static_cast<uint64_t>(rows) > Remaining() / sizeof(S) / cols)) {
      throw Error("simulation cache: a matrix has the wrong size");
    }
    m.resize(rows, cols);
    Raw(m.data(), sizeof(S) * m.size());
  }
  void Get(Eigen::Quaterniond& q) { Get(q.coeffs()); }
  void Get(std::vector<bool>& flags) {
    flags.resize(Size());
    for (size_t i = 0; i < flags.size(); ++i) {
      bool flag = false;
      Get(flag);
      flags[i] = flag;
    }
  }
  template <class A, class B>
  void Get(std::pair<A, B>& pair) {
    (*this)(pair.first);
    (*this)(pair.second);
  }
  template <class T>
  void Get(std::vector<T>& items) {
    items.resize(Size());
    for (T& item : items) (*this)(item);
  }
  template <class T>
  auto Get(T& value) -> decltype(VisitFields(*this, value)) {
    VisitFields(*this, value);
  }

  std::istream& in_;
  uint64_t size_;
  uint64_t offset_ = 0;
};

// Every field of each stored type, in one order for writing and reading (found by
// argument-dependent lookup through the archive, which lives in this namespace).
template <class A>
void VisitFields(A& a, geometry::Pose3d& pose) {
  a(pose.q);
  a(pose.p);
}
template <class A>
void VisitFields(A& a, sensors::ImuSample& s) {
  a(s.t_ns);
  a(s.gyro_rad_s);
  a(s.accel_m_s2);
}
template <class A>
void VisitFields(A& a, sensors::WheelSample& s) {
  a(s.t_ns);
  a(s.left_rad_s);
  a(s.right_rad_s);
}
template <class A>
void VisitFields(A& a, sensors::GnssFix& s) {
  a(s.t_ns);
  a(s.lat_deg);
  a(s.lon_deg);
  a(s.alt_m);
  a(s.std_enu_m);
}
template <class A>
void VisitFields(A& a, io::TrajectorySample& s) {
  a(s.t_ns);
  a(s.T_W_I);
  a(s.v_W_I);
}
template <class A>
void VisitFields(A& a, lidar::LidarSweep& s) {
  a(s.t_ns);
  a(s.cloud.points);
  a(s.cloud.intensity);
  a(s.cloud.time_s);
}
template <class A>
void VisitFields(A& a, sim::SimulatedLog& log) {
  a(log.imu.samples);
  a(log.imu.gyro_bias);
  a(log.imu.accel_bias);
  a(log.imu.truth);
  a(log.wheel);
  a(log.gnss.fixes);
  a(log.gnss.is_outlier);
  a(log.gnss.true_p_W_A);
  a(log.gnss.outages_s);
  a(log.sweeps);
}
template <class A>
void VisitFields(A& a, sensors::Calibration& c) {
  a(c.q_I_L);
  a(c.p_I_L);
  a(c.time_offset_lidar_imu_s);
  a(c.q_I_V);
  a(c.p_I_V);
  a(c.wheel_radius_left_m);
  a(c.wheel_radius_right_m);
  a(c.track_width_m);
  a(c.p_I_A);
  a(c.wheel_speed_scale_left);
  a(c.wheel_speed_scale_right);
  a(c.odometry_speed_scale);
  a(c.effective_track_m);
  a(c.time_offset_wheel_imu_s);
  a(c.time_offset_gnss_imu_s);
}
template <class A>
void VisitFields(A& a, sim::SimulationSummary& s) {
  a(s.scenario);
  a(s.duration_s);
  a(s.distance_m);
  a(s.min_speed_m_s);
  a(s.max_speed_m_s);
  a(s.max_yaw_rate_deg_s);
  a(s.total_turn_deg);
  a(s.max_lateral_accel_m_s2);
  a(s.min_pitch_deg);
  a(s.max_pitch_deg);
  a(s.min_roll_deg);
  a(s.max_roll_deg);
  a(s.standstill_s);
  a(s.imu_samples);
  a(s.wheel_samples);
  a(s.gnss_fixes);
  a(s.gnss_outliers);
  a(s.gnss_outages);
  a(s.gnss_outage_s);
  a(s.sweeps);
  a(s.points);
  a(s.imu_rate_hz);
  a(s.wheel_rate_hz);
  a(s.gnss_rate_hz);
  a(s.time_offset_wheel_imu_s);
  a(s.time_offset_gnss_imu_s);
  a(s.true_calibration);
  a(s.nominal_calibration);
}

// Every field of the options, for the key. A field added to SimulationOptions (or to a struct
// it holds) changes its size and stops the build here: add the field to the list below.
static_assert(sizeof(sim::SimulationOptions) == 880,
              "sim::SimulationOptions changed: list its new fields in the cache key");
template <class A>
void VisitFields(A& a, sim::SimulationOptions& o) {
  a(o.scenario);
  a(o.duration_s);
  a(o.seed);
  a(o.start_time_ns);
  a(o.dynamics.roll_per_lateral_accel);
  a(o.dynamics.pitch_per_longitudinal_accel);
  a(o.dynamics.rear_slip_per_lateral_accel);
  a(o.dynamics.rear_axle_height_m);
  a(o.imu.add_noise);
  a(o.imu.noise.gyroscope_noise_density);
  a(o.imu.noise.gyroscope_random_walk);
  a(o.imu.noise.accelerometer_noise_density);
  a(o.imu.noise.accelerometer_random_walk);
  a(o.imu.noise.update_rate_hz);
  a(o.imu.noise.max_sample_interval_s);
  a(o.imu.noise.dropout_gyro_sigma_rad_s);
  a(o.imu.noise.dropout_accel_sigma_m_s2);
  a(o.imu.noise_scale);
  double random_walk_scale = o.imu.random_walk_scale.value_or(-1.0);
  a(random_walk_scale);
  a(o.imu.initial_gyro_bias_sigma_rad_s);
  a(o.imu.initial_accel_bias_sigma_m_s2);
  a(o.imu.gravity_m_s2);
  a(o.imu.stamp_jitter_s);
  a(o.lidar.enabled);
  a(o.lidar.config.num_beams);
  a(o.lidar.config.rate_hz);
  a(o.lidar.config.min_elevation_deg);
  a(o.lidar.config.max_elevation_deg);
  a(o.lidar.config.azimuth_resolution_deg);
  a(o.lidar.config.min_range_m);
  a(o.lidar.config.max_range_m);
  a(o.lidar.config.range_noise_m);
  a(o.lidar.add_noise);
  a(o.lidar.dropout_probability);
  a(o.lidar.stamp_at_end);
  a(o.wheel.enabled);
  a(o.wheel.config.rate_hz);
  a(o.wheel.config.noise_rad_s);
  a(o.wheel.config.form);
  a(o.wheel.config.noise_m_s);
  a(o.wheel.config.yaw_rate_noise_rad_s);
  bool has_controller_track = o.wheel.config.controller_track_m.has_value();
  double controller_track_m = o.wheel.config.controller_track_m.value_or(0.0);
  a(has_controller_track);  // the options are only written into the key
  a(controller_track_m);
  a(o.wheel.config.lateral_slip_sigma_m_s);
  a(o.wheel.config.cornering_compliance_rad_per_m_s2);
  a(o.wheel.add_noise);
  a(o.wheel.time_offset_wheel_imu_s);
  a(o.wheel.stamp_jitter_s);
  a(o.wheel.burst_size);
  a(o.wheel.burst_span_s);
  a(o.wheel.drop_probability);
  a(o.gnss.enabled);
  a(o.gnss.config.rate_hz);
  a(o.gnss.std_enu_m);
  a(o.gnss.add_noise);
  a(o.gnss.num_outages);
  a(o.gnss.outage_duration_s);
  a(o.gnss.outlier_probability);
  a(o.gnss.origin_lat_deg);
  a(o.gnss.origin_lon_deg);
  a(o.gnss.origin_alt_m);
  a(o.gnss.time_offset_gnss_imu_s);
  a(o.gnss.error_correlation_time_s);
  a(o.true_calibration);
  a(o.nominal_perturbation.rotation_deg);
  a(o.nominal_perturbation.translation_m);
  a(o.nominal_perturbation.time_offset_s);
  a(o.nominal_perturbation.wheel_radius_sigma_m);
  a(o.nominal_perturbation.track_width_sigma_m);
  a(o.nominal_perturbation.state_uncertainty);
  // The options are only written (into the key): the optional goes in as a flag and a value.
  bool has_nominal_q_I_V = o.nominal_perturbation.q_I_V.has_value();
  Eigen::Quaterniond nominal_q_I_V =
      o.nominal_perturbation.q_I_V.value_or(Eigen::Quaterniond::Identity());
  a(has_nominal_q_I_V);
  a(nominal_q_I_V);
  a(o.nominal_perturbation.q_I_V_sigma_deg);
  a(o.nominal_wheel_radius_m);
  a(o.nominal_track_width_m);
}

// Bump when the stored form changes.
constexpr int kFormatVersion = 3;  // 2: clocks and stamp models; 3: wheel-form blocks

inline std::string Hex64(const std::string& bytes) {
  uint64_t hash = 14695981039346656037ull;  // FNV-1a, 64 bit
  for (unsigned char c : bytes) hash = (hash ^ c) * 1099511628211ull;
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(hash));
  return text;
}

inline std::string OptionsKey(const sim::SimulationOptions& options) {
  sim::SimulationOptions copy = options;
  Writer writer;
  int version = kFormatVersion;
  writer(version);
  writer(copy);
  return Hex64(writer.bytes());
}

// Size and modification time of the running program: a new stamp after every relink.
inline std::string BuildStamp() {
  struct stat program;
  if (::stat("/proc/self/exe", &program) != 0) throw Error("simulation cache: no /proc/self/exe");
  return std::to_string(program.st_size) + "-" + std::to_string(program.st_mtim.tv_sec) + "." +
         std::to_string(program.st_mtim.tv_nsec);
}

inline std::filesystem::path CacheRoot() {
  return std::filesystem::path(AUTOCAL_TEST_OUTPUT_DIR) / "fixture_cache";
}

inline std::string ReadFile(const std::filesystem::path& path) {
  std::error_code error;
  const uintmax_t size = std::filesystem::file_size(path, error);
  std::ifstream in(path, std::ios::binary);
  std::string bytes(error ? 0 : size, '\0');
  if (error || !in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()))) {
    throw Error("simulation cache: cannot read " + path.string());
  }
  return bytes;
}

inline void WriteFile(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out.flush()) throw Error("simulation cache: cannot write " + path.string());
}

// Reads `value` from the file `path` that Writer wrote; throws autocal::Error when it is short
// or too long.
template <class T>
void Load(const std::filesystem::path& path, T* value) {
  std::error_code error;
  const uintmax_t size = std::filesystem::file_size(path, error);
  std::ifstream in(path, std::ios::binary);
  if (error || !in) throw Error("simulation cache: cannot read " + path.string());
  Reader reader(in, size);
  reader(*value);
  if (!reader.at_end()) throw Error("simulation cache: " + path.string() + " is too long");
}

// The entry directory <root>/<stamp>/<name>; on a miss, `make(directory)` fills a private
// temporary directory that is then renamed into place.
template <class Make>
std::filesystem::path Entry(const std::string& name, Make make) {
  namespace fs = std::filesystem;
  const std::string stamp = BuildStamp();
  const fs::path entry = CacheRoot() / stamp / name;
  if (fs::is_directory(entry)) return entry;
  fs::create_directories(entry.parent_path());
  std::error_code ignored;
  for (const fs::directory_entry& old : fs::directory_iterator(CacheRoot())) {
    if (old.path().filename() != stamp) fs::remove_all(old.path(), ignored);
  }
  const fs::path temporary =
      entry.parent_path() / (name + ".partial-" + std::to_string(static_cast<long>(getpid())));
  fs::remove_all(temporary);
  fs::create_directories(temporary);
  make(temporary);
  std::error_code error;
  fs::rename(temporary, entry, error);
  if (error) {
    // Another process made the entry first: it holds the same bytes.
    fs::remove_all(temporary, ignored);
    if (!fs::is_directory(entry)) throw Error("simulation cache: cannot make " + entry.string());
  }
  return entry;
}

}  // namespace simulation_cache

// Any value the archive can store (vectors, Eigen matrices, LiDAR sweeps, ...), made by
// `make()` once per test program and build. `name` must tell apart everything the program
// caches this way (letters, digits and '_'); the build stamp covers changes of the code that
// makes it.
template <class T, class Make>
T CachedValue(const std::string& name, Make make) {
  namespace cache = simulation_cache;
  const std::filesystem::path entry =
      cache::Entry(name + "-value", [&](const std::filesystem::path& dir) {
        T value = make();
        cache::Writer writer;
        writer(value);
        cache::WriteFile(dir / "value.bin", writer.bytes());
      });
  T value;
  cache::Load(entry / "value.bin", &value);
  return value;
}

// sim::Simulate(simulator), simulated once per test program and build.
inline sim::SimulatedLog CachedSimulatedLog(const sim::Simulator& simulator) {
  namespace cache = simulation_cache;
  const std::string name = cache::OptionsKey(simulator.options()) + "-log";
  const std::filesystem::path entry = cache::Entry(name, [&](const std::filesystem::path& dir) {
    sim::SimulatedLog log = sim::Simulate(simulator);
    cache::Writer writer;
    writer(log);
    cache::WriteFile(dir / "log.bin", writer.bytes());
  });
  sim::SimulatedLog log;
  cache::Load(entry / "log.bin", &log);
  return log;
}

// sim::WriteDataset(simulator, ...) once per test program and build: the dataset directory
// (shared by every test of the program: read it, never write into it) and its summary.
struct CachedDatasetEntry {
  std::string directory;
  sim::SimulationSummary summary;
};
inline CachedDatasetEntry CachedDataset(const sim::Simulator& simulator) {
  namespace cache = simulation_cache;
  const std::string name = cache::OptionsKey(simulator.options()) + "-dataset";
  const std::filesystem::path entry = cache::Entry(name, [&](const std::filesystem::path& dir) {
    sim::SimulationSummary summary = sim::WriteDataset(simulator, (dir / "dataset").string());
    cache::Writer writer;
    writer(summary);
    cache::WriteFile(dir / "summary.bin", writer.bytes());
  });
  CachedDatasetEntry result;
  result.directory = (entry / "dataset").string();
  cache::Load(entry / "summary.bin", &result.summary);
  return result;
}

}  // namespace test
}  // namespace autocal
