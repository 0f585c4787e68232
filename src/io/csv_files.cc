#include "autocal/io/csv_files.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/estimation/initialization.h"
#include "autocal/io/point_cloud_file.h"
#include "common/order_statistics.h"
#include "estimation/gyro_unit.h"
#include "io/csv_format.h"
#include "io/csv_reader.h"
#include "io/text_format.h"

namespace autocal {
namespace io {
namespace internal {

const std::vector<std::string>& ImuColumns() {
  static const std::vector<std::string> kColumns = {"t_ns", "gx", "gy", "gz", "ax", "ay", "az"};
  return kColumns;
}
const std::vector<std::string>& WheelColumns() {
  static const std::vector<std::string> kColumns = {"t_ns", "left_rad_s", "right_rad_s"};
  return kColumns;
}
const std::vector<std::string>& WheelSpeedColumns(bool four_wheels) {
  static const std::vector<std::string> kRear = {"t_ns", "left_m_s", "right_m_s"};
  static const std::vector<std::string> kFour = {"t_ns", "left_m_s", "right_m_s", "front_left_m_s",
                                                 "front_right_m_s"};
  return four_wheels ? kFour : kRear;
}
const std::vector<std::string>& OdometryColumns() {
  static const std::vector<std::string> kColumns = {"t_ns", "speed_m_s", "yaw_rate_rad_s"};
  return kColumns;
}
const std::vector<std::string>& GnssColumns() {
  static const std::vector<std::string> kColumns = {"t_ns",       "lat_deg",     "lon_deg", "alt_m",
                                                    "std_east_m", "std_north_m", "std_up_m"};
  return kColumns;
}
const std::vector<std::string>& LidarColumns() {
  static const std::vector<std::string> kColumns = {"t_ns", "file"};
  return kColumns;
}
const std::vector<std::string>& TrajectoryColumns() {
  static const std::vector<std::string> kColumns = {"t_ns", "px", "py", "pz", "qx", "qy",
                                                    "qz",   "qw", "vx", "vy", "vz"};
  return kColumns;
}

const std::vector<std::string>& ImuBiasColumns() {
  static const std::vector<std::string> kColumns = {"t_ns", "bgx", "bgy", "bgz",
                                                    "bax",  "bay", "baz"};
  return kColumns;
}

std::string HeaderLine(const std::vector<std::string>& columns) {
  std::string line;
  for (const std::string& column : columns) line += (line.empty() ? "" : ",") + column;
  return line + "\n";
}

void CheckSweepFileName(const std::string& file) {
  const bool bad = file.empty() || file[0] == '/' || file.find("..") != std::string::npos ||
                   file.find_first_of(",\n\r") != std::string::npos || Trim(file) != file;
  if (bad)
    throw Error("invalid sweep file name '" + file +
                "' (relative to lidar/, no ',', '..' or blanks)");
  // The formats LoadSweep reads, told here rather than halfway through a run.
  if (!IsPointCloudFileName(file)) {
    throw Error("sweep file '" + file + "' is neither .ply nor .pcd");
  }
}

std::string LidarRow(const LidarSweepRef& sweep) {
  CheckSweepFileName(sweep.file);
  return std::to_string(sweep.t_ns) + "," + sweep.file + "\n";
}

}  // namespace internal

namespace {

using internal::CsvReader;
using internal::FormatDouble;

// ---- writing ----

// Appends the doubles of one row, refusing what the reader would refuse.
void AppendNumbers(const std::vector<double>& values, const std::string& path, size_t row,
                   std::string* out) {
  for (double value : values) {
    if (!std::isfinite(value)) {
      throw Error("cannot write '" + path + "': row " + std::to_string(row) +
                  " has a non-finite value");
    }
    *out += ',';
    *out += FormatDouble(value);
  }
  *out += '\n';
}

void CheckIncreasing(int64_t previous_ns, int64_t t_ns, size_t row, const std::string& path) {
  if (row > 0 && t_ns <= previous_ns) {
    throw Error("cannot write '" + path + "': row " + std::to_string(row) + " has t_ns " +
                std::to_string(t_ns) + " <= previous " + std::to_string(previous_ns) +
                " (timestamps must strictly increase)");
  }
}

template <typename Sample, typename Numbers>
void WriteRows(const std::string& path, const std::vector<std::string>& columns,
               const std::vector<Sample>& samples, Numbers numbers) {
  std::string text = internal::HeaderLine(columns);
  for (size_t i = 0; i < samples.size(); ++i) {
    if (i > 0) CheckIncreasing(samples[i - 1].t_ns, samples[i].t_ns, i, path);
    text += std::to_string(samples[i].t_ns);
    AppendNumbers(numbers(samples[i]), path, i, &text);
  }
  internal::WriteFileText(path, text);
}

// ---- plausibility of imu.csv ----

struct ImuRowPosition {
  int64_t line = 0;
  int64_t gyro_column = 0;
  int64_t accel_column = 0;
};

// printf-style formatting for messages with numbers.
std::string Printf(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string Printf(const char* format, ...) {
  char buffer[512];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buffer, sizeof(buffer), format, args);
  va_end(args);
  return buffer;
}

// Refuses the first row that reads beyond any IMU's full scale (ImuPlausibilityOptions), from
// each row's |omega| and |a|.
void CheckFullScale(const CsvReader& reader, const std::vector<double>& rates_rad_s,
                    const std::vector<double>& accels_m_s2, const std::vector<ImuRowPosition>& rows,
                    const ImuPlausibilityOptions& checks) {
  const double max_accel_m_s2 = checks.max_sample_accel_g * checks.gravity_m_s2;
  for (size_t i = 0; i < rates_rad_s.size(); ++i) {
    const double gyro = rates_rad_s[i], accel = accels_m_s2[i];
    if (gyro > checks.max_sample_gyro_rad_s) {
      reader.FailAt(rows[i].line, rows[i].gyro_column,
                    Printf("|omega| = %.3g rad/s, beyond any gyroscope's range (%.3g rad/s): a "
                           "corrupt row",
                           gyro, checks.max_sample_gyro_rad_s));
    }
    if (accel > max_accel_m_s2) {
      reader.FailAt(rows[i].line, rows[i].accel_column,
                    Printf("|a| = %.3g m/s^2 = %.3g g, beyond any accelerometer's range (%.3g g): "
                           "a corrupt row",
                           accel, accel / checks.gravity_m_s2, checks.max_sample_accel_g));
    }
  }
}

void CheckImuPlausibility(const CsvReader& reader, const sensors::ImuSamples& samples,
                          const std::vector<ImuRowPosition>& rows,
                          const ImuPlausibilityOptions& checks) {
  if (!checks.enabled || samples.empty()) return;
  std::vector<double> rates(samples.size());
  for (size_t i = 0; i < samples.size(); ++i) rates[i] = samples[i].gyro_rad_s.norm();
  std::vector<double> sorted = rates;
  const size_t k =
      std::min(sorted.size() - 1,
               static_cast<size_t>(checks.gyro_percentile * static_cast<double>(sorted.size())));
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(k), sorted.end());
  const double percentile = sorted[k];
  if (percentile > checks.max_gyro_percentile_rad_s) {
    size_t first = 0;
    while (rates[first] <= checks.max_gyro_percentile_rad_s) ++first;
    reader.FailAt(
        rows[first].line, rows[first].gyro_column,
        Printf("gyroscope seems to be in deg/s, autocal expects rad/s: the %.0fth "
               "percentile of |omega| over the log is %.3g rad/s, beyond any car "
               "(limit %.3g rad/s); this is the first row above the limit",
               100.0 * checks.gyro_percentile, percentile, checks.max_gyro_percentile_rad_s));
  }
  if (checks.check_gyro_unit_at_rest) {
    // A log that never turns fast passes the percentile; at rest the noise tells.
    const double stated_std_rad_s =
        checks.gyroscope_noise_density * std::sqrt(checks.update_rate_hz);
    const auto degrees =
        estimation::internal::FindGyroInDegreesAtRest(samples, estimation::StillStartOptions());
    if (degrees && degrees->gyro_std_as_read > checks.max_still_noise_ratio * stated_std_rad_s) {
      const ImuRowPosition& row = rows[degrees->first_sample];
      reader.FailAt(
          row.line, row.gyro_column,
          Printf("gyroscope seems to be in deg/s, autocal expects rad/s: from this row the "
                 "accelerometer is steady for %.1f s (the vehicle at rest), but the gyro "
                 "scatters by %.3g (per-axis std) around %.3g; read as deg/s that is %.3g rad/s "
                 "around %.3g rad/s, a still gyro's noise (stated: %.3g rad/s) and bias",
                 degrees->duration_s, degrees->gyro_std_as_read, degrees->gyro_mean_as_read,
                 degrees->gyro_std_as_read * kDegToRad, degrees->gyro_mean_as_read * kDegToRad,
                 stated_std_rad_s));
    }
  }
  std::vector<double> accel(samples.size());
  for (size_t i = 0; i < samples.size(); ++i) accel[i] = samples[i].accel_m_s2.norm();
  const double median_g = autocal::internal::Median(accel) / checks.gravity_m_s2;
  if (median_g < checks.min_median_accel_g) {
    const bool looks_like_g = std::abs(median_g * checks.gravity_m_s2 - 1.0) < 0.2;
    reader.FailAt(
        rows[0].line, rows[0].accel_column,
        Printf("median |a| over the log is %.3g m/s^2 = %.3g g: ", median_g * checks.gravity_m_s2,
               median_g) +
            (looks_like_g ? "the accelerometer seems to be in units of g; autocal expects m/s^2"
                          : "accelerometer seems to exclude gravity; autocal expects "
                            "specific force (gravity included) in m/s^2"));
  }
  if (median_g > checks.max_median_accel_g) {
    reader.FailAt(rows[0].line, rows[0].accel_column,
                  Printf("median |a| over the log is %.3g m/s^2 = %.3g g, far above gravity: the "
                         "accelerometer unit is not m/s^2",
                         median_g * checks.gravity_m_s2, median_g));
  }
  CheckFullScale(reader, rates, accel, rows, checks);
}

// ---- the unit of the stamps ----

// Where a row's stamp is, for messages.
struct StampPosition {
  int64_t line = 0;
  int64_t column = 0;
};

// Refuses stamps that are not nanoseconds: a sensor cannot run faster than max_rate_hz, so a
// median interval shorter than 1 / max_rate_hz means another unit (microseconds make a 100 Hz
// encoder look like 100 kHz). The median ignores bursts and dropouts; ten intervals at least.
template <typename Samples>
void CheckStampUnit(const CsvReader& reader, const Samples& samples,
                    const std::vector<StampPosition>& rows, double max_rate_hz,
                    const char* sensor) {  // with its article: "an IMU"
  constexpr size_t kMinIntervals = 10;
  if (samples.size() < kMinIntervals + 1) return;
  std::vector<int64_t> intervals_ns(samples.size() - 1);
  for (size_t i = 1; i < samples.size(); ++i) {
    intervals_ns[i - 1] = samples[i].t_ns - samples[i - 1].t_ns;
  }
  const auto middle = intervals_ns.begin() + static_cast<std::ptrdiff_t>(intervals_ns.size() / 2);
  std::nth_element(intervals_ns.begin(), middle, intervals_ns.end());
  const double median_s = static_cast<double>(*middle) * 1e-9;
  if (median_s * max_rate_hz >= 1.0) return;
  // The smallest power of 1000 that brings the rate below the limit names the likely unit.
  const char* unit = median_s * 1e3 * max_rate_hz >= 1.0   ? "microseconds"
                     : median_s * 1e6 * max_rate_hz >= 1.0 ? "milliseconds"
                                                           : "a unit finer than nanoseconds";
  reader.FailAt(rows[1].line, rows[1].column,
                Printf("t_ns: the median interval between rows is %lld ns, %s at %.0f Hz, "
                       "beyond any (limit %.0f Hz): the stamps seem to be in %s; autocal expects "
                       "nanoseconds",
                       static_cast<long long>(*middle), sensor, 1.0 / median_s, max_rate_hz, unit));
}

}  // namespace

sensors::ImuSamples ReadImuCsv(const std::string& path, const ImuPlausibilityOptions& checks) {
  CsvReader reader(path, internal::ImuColumns());
  sensors::ImuSamples samples;
  std::vector<ImuRowPosition> rows;
  std::vector<StampPosition> stamps;
  while (reader.Next()) {
    sensors::ImuSample sample;
    sample.t_ns = reader.Timestamp();
    for (int i = 0; i < 3; ++i) {
      sample.gyro_rad_s[i] = reader.Double(1 + i);
      sample.accel_m_s2[i] = reader.Double(4 + i);
    }
    samples.push_back(sample);
    rows.push_back({reader.line(), reader.column(1), reader.column(4)});
    stamps.push_back({reader.line(), reader.column(0)});
  }
  if (samples.empty()) reader.FailAt(2, 1, "no IMU samples after the header");
  CheckStampUnit(reader, samples, stamps, kMaxPlausibleImuRateHz, "an IMU");
  CheckImuPlausibility(reader, samples, rows, checks);
  return samples;
}

sensors::WheelSamples ReadWheelCsv(const std::string& path) {
  CsvReader reader(path, internal::WheelColumns());
  sensors::WheelSamples samples;
  std::vector<StampPosition> stamps;
  while (reader.Next()) {
    sensors::WheelSample sample;
    sample.t_ns = reader.Timestamp();
    sample.left_rad_s = reader.Double(1);
    sample.right_rad_s = reader.Double(2);
    for (size_t field : {1, 2}) {
      const double rate = field == 1 ? sample.left_rad_s : sample.right_rad_s;
      if (std::abs(rate) > kMaxPlausibleWheelRateRadS) {
        reader.Fail(field, Printf("wheel rate %.4g rad/s is beyond any car (limit %.0f rad/s): "
                                  "is the column in rpm or deg/s?",
                                  rate, kMaxPlausibleWheelRateRadS));
      }
    }
    samples.push_back(sample);
    stamps.push_back({reader.line(), reader.column(0)});
  }
  CheckStampUnit(reader, samples, stamps, kMaxPlausibleWheelSampleRateHz, "a wheel encoder");
  return samples;
}

namespace {

// Whether the header line of wheel_speed.csv names more than three columns: the four-wheel
// layout. Its columns are then checked by the reader like any header.
bool HasFourWheelHeader(const std::string& path) {
  const std::string bytes = internal::ReadFileBytes(path);
  const std::string_view first(bytes.data(), std::min(bytes.find('\n'), bytes.size()));
  return std::count(first.begin(), first.end(), ',') > 2;
}

}  // namespace

sensors::WheelSpeedSamples ReadWheelSpeedCsv(const std::string& path) {
  const bool four_wheels = HasFourWheelHeader(path);
  CsvReader reader(path, internal::WheelSpeedColumns(four_wheels));
  sensors::WheelSpeedSamples samples;
  std::vector<StampPosition> stamps;
  while (reader.Next()) {
    sensors::WheelSpeedSample sample;
    sample.t_ns = reader.Timestamp();
    double* speeds[] = {&sample.left_m_s, &sample.right_m_s, &sample.front_left_m_s,
                        &sample.front_right_m_s};
    sample.has_front = four_wheels;
    for (size_t field = 1; field < (four_wheels ? 5u : 3u); ++field) {
      *speeds[field - 1] = reader.Double(field);
      if (std::abs(*speeds[field - 1]) > kMaxPlausibleWheelSpeedMS) {
        reader.Fail(field, Printf("wheel speed %.4g m/s is beyond any car (limit %.0f m/s): is "
                                  "the column in km/h or mph?",
                                  *speeds[field - 1], kMaxPlausibleWheelSpeedMS));
      }
    }
    samples.push_back(sample);
    stamps.push_back({reader.line(), reader.column(0)});
  }
  CheckStampUnit(reader, samples, stamps, kMaxPlausibleWheelSampleRateHz, "a wheel-speed sensor");
  return samples;
}

sensors::OdometrySamples ReadOdometryCsv(const std::string& path) {
  CsvReader reader(path, internal::OdometryColumns());
  sensors::OdometrySamples samples;
  std::vector<StampPosition> stamps;
  while (reader.Next()) {
    sensors::OdometrySample sample;
    sample.t_ns = reader.Timestamp();
    sample.speed_m_s = reader.Double(1);
    if (std::abs(sample.speed_m_s) > kMaxPlausibleWheelSpeedMS) {
      reader.Fail(1, Printf("speed %.4g m/s is beyond any vehicle (limit %.0f m/s): is the "
                            "column in km/h or mph?",
                            sample.speed_m_s, kMaxPlausibleWheelSpeedMS));
    }
    sample.yaw_rate_rad_s = reader.Double(2);
    if (std::abs(sample.yaw_rate_rad_s) > kMaxPlausibleYawRateRadS) {
      reader.Fail(2, Printf("yaw rate %.4g rad/s is beyond any vehicle (limit %.0f rad/s): is "
                            "the column in deg/s?",
                            sample.yaw_rate_rad_s, kMaxPlausibleYawRateRadS));
    }
    samples.push_back(sample);
    stamps.push_back({reader.line(), reader.column(0)});
  }
  CheckStampUnit(reader, samples, stamps, kMaxPlausibleWheelSampleRateHz, "a vehicle odometry");
  return samples;
}

sensors::GnssFixes ReadGnssCsv(const std::string& path) {
  CsvReader reader(path, internal::GnssColumns());
  sensors::GnssFixes fixes;
  std::vector<StampPosition> stamps;
  while (reader.Next()) {
    sensors::GnssFix fix;
    fix.t_ns = reader.Timestamp();
    fix.lat_deg = reader.Double(1);
    if (std::abs(fix.lat_deg) > 90.0) reader.Fail(1, "latitude must be within [-90, 90] deg");
    fix.lon_deg = reader.Double(2);
    if (std::abs(fix.lon_deg) > 180.0) reader.Fail(2, "longitude must be within [-180, 180] deg");
    fix.alt_m = reader.Double(3);
    for (int i = 0; i < 3; ++i) {
      fix.std_enu_m[i] = reader.Double(4 + i);
      if (!(fix.std_enu_m[i] > 0.0)) reader.Fail(4 + i, "a standard deviation must be > 0");
    }
    fixes.push_back(fix);
    stamps.push_back({reader.line(), reader.column(0)});
  }
  CheckStampUnit(reader, fixes, stamps, kMaxPlausibleGnssRateHz, "a GNSS receiver");
  return fixes;
}

std::vector<LidarSweepRef> ReadLidarCsv(const std::string& path,
                                        const std::string& sweep_directory) {
  CsvReader reader(path, internal::LidarColumns());
  std::vector<LidarSweepRef> sweeps;
  std::vector<StampPosition> stamps;
  while (reader.Next()) {
    LidarSweepRef sweep;
    sweep.t_ns = reader.Timestamp();
    sweep.file = std::string(reader.Text(1));
    try {
      internal::CheckSweepFileName(sweep.file);
    } catch (const Error& e) {
      reader.Fail(1, e.what());
    }
    if (!sweep_directory.empty()) {
      const std::filesystem::path full = std::filesystem::path(sweep_directory) / sweep.file;
      std::error_code error;
      if (!std::filesystem::is_regular_file(full, error)) {
        reader.Fail(1, "sweep file " + internal::Quote(sweep.file) + " not found (looked for '" +
                           full.string() + "')");
      }
    }
    sweeps.push_back(sweep);
    stamps.push_back({reader.line(), reader.column(0)});
  }
  CheckStampUnit(reader, sweeps, stamps, kMaxPlausibleSweepRateHz, "a LiDAR");
  return sweeps;
}

Trajectory ReadTrajectoryCsv(const std::string& path) {
  CsvReader reader(path, internal::TrajectoryColumns());
  Trajectory trajectory;
  while (reader.Next()) {
    TrajectorySample sample;
    sample.t_ns = reader.Timestamp();
    for (int i = 0; i < 3; ++i) sample.T_W_I.p[i] = reader.Double(1 + i);
    Eigen::Vector4d xyzw;
    for (int i = 0; i < 4; ++i) xyzw[i] = reader.Double(4 + i);
    const double norm = xyzw.norm();
    if (std::abs(norm - 1.0) > 1e-3) {
      reader.Fail(4, Printf("quaternion (qx, qy, qz, qw) has norm %.6g, not a rotation (|norm - 1| "
                            "must be <= 1e-3)",
                            norm));
    }
    // Below 1e-15, |q| - 1 is rounding: keep the digits so that files round trip exactly.
    if (std::abs(norm - 1.0) > 1e-15) xyzw /= norm;
    sample.T_W_I.q = Eigen::Quaterniond(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
    for (int i = 0; i < 3; ++i) sample.v_W_I[i] = reader.Double(8 + i);
    trajectory.push_back(sample);
  }
  return trajectory;
}

ImuBiasTrajectory ReadImuBiasCsv(const std::string& path) {
  CsvReader reader(path, internal::ImuBiasColumns());
  ImuBiasTrajectory biases;
  while (reader.Next()) {
    ImuBiasSample sample;
    sample.t_ns = reader.Timestamp();
    for (int i = 0; i < 3; ++i) sample.b_g[i] = reader.Double(1 + i);
    for (int i = 0; i < 3; ++i) sample.b_a[i] = reader.Double(4 + i);
    biases.push_back(sample);
  }
  return biases;
}

void WriteImuCsv(const std::string& path, const sensors::ImuSamples& samples) {
  WriteRows(path, internal::ImuColumns(), samples, [](const sensors::ImuSample& s) {
    return std::vector<double>{s.gyro_rad_s.x(), s.gyro_rad_s.y(), s.gyro_rad_s.z(),
                               s.accel_m_s2.x(), s.accel_m_s2.y(), s.accel_m_s2.z()};
  });
}

void WriteWheelCsv(const std::string& path, const sensors::WheelSamples& samples) {
  WriteRows(path, internal::WheelColumns(), samples, [](const sensors::WheelSample& s) {
    return std::vector<double>{s.left_rad_s, s.right_rad_s};
  });
}

void WriteWheelSpeedCsv(const std::string& path, const sensors::WheelSpeedSamples& samples) {
  const bool four_wheels = !samples.empty() && samples.front().has_front;
  for (size_t i = 0; i < samples.size(); ++i) {
    if (samples[i].has_front != four_wheels) {
      throw Error("cannot write '" + path + "': row " + std::to_string(i) +
                  (four_wheels ? " lacks" : " has") +
                  " the front wheels, unlike row 0 (one layout per file)");
    }
  }
  WriteRows(path, internal::WheelSpeedColumns(four_wheels), samples,
            [four_wheels](const sensors::WheelSpeedSample& s) {
              return four_wheels ? std::vector<double>{s.left_m_s, s.right_m_s, s.front_left_m_s,
                                                       s.front_right_m_s}
                                 : std::vector<double>{s.left_m_s, s.right_m_s};
            });
}

void WriteOdometryCsv(const std::string& path, const sensors::OdometrySamples& samples) {
  WriteRows(path, internal::OdometryColumns(), samples, [](const sensors::OdometrySample& s) {
    return std::vector<double>{s.speed_m_s, s.yaw_rate_rad_s};
  });
}

void WriteGnssCsv(const std::string& path, const sensors::GnssFixes& fixes) {
  WriteRows(path, internal::GnssColumns(), fixes, [](const sensors::GnssFix& f) {
    return std::vector<double>{f.lat_deg,       f.lon_deg,       f.alt_m,
                               f.std_enu_m.x(), f.std_enu_m.y(), f.std_enu_m.z()};
  });
}

void WriteLidarCsv(const std::string& path, const std::vector<LidarSweepRef>& sweeps) {
  std::string text = internal::HeaderLine(internal::LidarColumns());
  for (size_t i = 0; i < sweeps.size(); ++i) {
    if (i > 0) CheckIncreasing(sweeps[i - 1].t_ns, sweeps[i].t_ns, i, path);
    text += internal::LidarRow(sweeps[i]);
  }
  internal::WriteFileText(path, text);
}

void WriteImuBiasCsv(const std::string& path, const ImuBiasTrajectory& biases) {
  WriteRows(path, internal::ImuBiasColumns(), biases, [](const ImuBiasSample& s) {
    return std::vector<double>{s.b_g.x(), s.b_g.y(), s.b_g.z(), s.b_a.x(), s.b_a.y(), s.b_a.z()};
  });
}

void WriteTrajectoryCsv(const std::string& path, const Trajectory& trajectory) {
  WriteRows(path, internal::TrajectoryColumns(), trajectory, [](const TrajectorySample& s) {
    const Eigen::Quaterniond& q = s.T_W_I.q;
    return std::vector<double>{s.T_W_I.p.x(), s.T_W_I.p.y(), s.T_W_I.p.z(), q.x(),
                               q.y(),         q.z(),         q.w(),         s.v_W_I.x(),
                               s.v_W_I.y(),   s.v_W_I.z()};
  });
}

}  // namespace io
}  // namespace autocal
