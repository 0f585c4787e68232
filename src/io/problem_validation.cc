// ValidateProblemForDataset (autocal/io/problem_yaml.h): whether a dataset holds what a
// problem uses, every shortfall named in one error.

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/io/calibration_block_fields.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/sensors/calibration_blocks.h"

namespace autocal {
namespace io {
namespace {

// What the problem does with a block, for messages: "estimates", "puts a prior on", or empty
// for a fixed block.
std::string Verb(BlockMode mode) {
  switch (mode) {
    case BlockMode::kEstimate:
      return "estimates";
    case BlockMode::kPrior:
      return "puts a prior on";
    case BlockMode::kFixed:
      return "";
  }
  return "";
}

struct NamedMode {
  const char* name;
  BlockMode mode;
};

// "estimates wheel_radius_left_m" for the first block that is not fixed, else `fallback`
// ("uses the wheel encoders"): a sensor whose blocks are all fixed still adds factors.
std::string Demand(const std::vector<NamedMode>& blocks, const std::string& fallback) {
  for (const NamedMode& block : blocks) {
    if (block.mode != BlockMode::kFixed) return Verb(block.mode) + " " + block.name;
  }
  return fallback;
}

// The blocks of `sensor` (of the dataset's wheel form) with their modes, for Demand: a wheel
// form's own intrinsics first (those of fewer forms before the track width, which two share),
// then the blocks of every form, in the block table's order.
std::vector<NamedMode> Demands(const ProblemCalibration& c, sensors::BlockSensor sensor,
                               sensors::WheelForm form) {
  const auto forms_of = [](sensors::CalibrationBlockId id) {
    int n = 0;
    for (sensors::WheelForm f :
         {sensors::WheelForm::kAngularRates, sensors::WheelForm::kLinearSpeeds,
          sensors::WheelForm::kSpeedYawRate}) {
      n += sensors::BlockInWheelForm(id, f) ? 1 : 0;
    }
    return n;
  };
  std::vector<sensors::CalibrationBlockId> ids;
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    if (info.sensor == sensor && sensors::BlockInWheelForm(info.id, form)) ids.push_back(info.id);
  }
  std::stable_sort(ids.begin(), ids.end(),
                   [&](auto a, auto b) { return forms_of(a) < forms_of(b); });
  std::vector<NamedMode> out;
  for (sensors::CalibrationBlockId id : ids) {
    out.push_back({ProblemKey(id), BlockSettingIn(c, id).mode});
  }
  return out;
}

// "has no wheel.csv", or "has no samples in wheel.csv" when the file is there but empty.
std::string Lacks(const Dataset& dataset, const char* file) {
  std::error_code error;
  const bool exists =
      std::filesystem::exists(std::filesystem::path(dataset.directory) / file, error);
  return exists ? std::string("has no samples in ") + file : std::string("has no ") + file;
}

// The LiDAR stamps on its own clock, offset from the IMU's by time_offset_lidar_imu_s: sweeps
// this close to the IMU's span count as inside it.
constexpr int64_t kLidarClockSlackNs = 1'000'000'000;

// Empty when some of `samples` lie within the IMU's time span (widened by slack_ns), else why
// not: "0 of 3950 samples of DIR/wheel.csv fall inside the IMU's time span (...)". A sensor
// whose stamps are in another unit or on another clock would otherwise add no factor.
template <typename Samples>
std::string OutsideImuSpan(const Dataset& dataset, const Samples& samples, const char* file,
                           int64_t slack_ns) {
  if (samples.empty() || dataset.imu.size() < 2) return "";
  const int64_t begin_ns = dataset.imu.front().t_ns - slack_ns;
  const int64_t end_ns = dataset.imu.back().t_ns + slack_ns;
  size_t inside = 0;
  for (const auto& sample : samples) inside += sample.t_ns >= begin_ns && sample.t_ns <= end_ns;
  if (inside > 0) return "";
  const int64_t first_ns = samples.front().t_ns;
  const int64_t last_ns = samples.back().t_ns;
  // Stamps in microseconds or milliseconds sit about 1e3 or 1e6 times closer to the epoch.
  std::string hint = "another clock?";
  for (const auto& [factor, unit] : {std::pair<int64_t, const char*>{1000, "microseconds"},
                                     std::pair<int64_t, const char*>{1000000, "milliseconds"}}) {
    if (last_ns <= end_ns / factor && last_ns >= begin_ns / factor) {
      hint = std::string("the stamps look like ") + unit + ", autocal expects nanoseconds";
    }
  }
  return "0 of " + std::to_string(samples.size()) + " samples of " +
         (std::filesystem::path(dataset.directory) / file).string() +
         " fall inside the IMU's time span (imu.csv " + std::to_string(dataset.imu.front().t_ns) +
         " to " + std::to_string(dataset.imu.back().t_ns) + " ns, " + file + " " +
         std::to_string(first_ns) + " to " + std::to_string(last_ns) + " ns: " + hint + ")";
}

}  // namespace

void ValidateProblemForDataset(const Problem& problem, const Dataset& dataset) {
  const ProblemCalibration& c = problem.calibration;
  const sensors::WheelForm form = dataset.wheel_form();
  const std::string who = "problem " + (problem.path.empty() ? "(built in code)" : problem.path);
  const std::string where = "dataset " + dataset.directory;
  std::vector<std::string> reasons;
  if (dataset.imu.size() < 2) {
    reasons.push_back(who + " needs the IMU but " + where + " has " +
                      std::to_string(dataset.imu.size()) + " IMU samples in imu.csv");
  }
  if (problem.sensors.lidar && dataset.lidar_sweeps.empty()) {
    const std::string demand =
        Demand(Demands(c, sensors::BlockSensor::kLidar, form), "uses the LiDAR");
    reasons.push_back(who + " " + demand + " but " + where + " " + Lacks(dataset, "lidar.csv"));
  }
  const char* wheel_file = sensors::WheelFormFile(form);
  if (problem.sensors.wheel && dataset.wheel_sample_count() == 0) {
    const std::string demand =
        Demand(Demands(c, sensors::BlockSensor::kWheel, form), "uses the wheel encoders");
    reasons.push_back(who + " " + demand + " but " + where + " " + Lacks(dataset, wheel_file));
  }
  if (problem.sensors.gnss && dataset.gnss.empty()) {
    const std::string demand = Demand(Demands(c, sensors::BlockSensor::kGnss, form), "uses GNSS");
    reasons.push_back(who + " " + demand + " but " + where + " " + Lacks(dataset, "gnss.csv"));
  }
  const auto add_outside = [&](const std::string& outside, const char* demand) {
    if (!outside.empty()) reasons.push_back(who + " " + demand + " but " + outside);
  };
  if (problem.sensors.lidar) {
    add_outside(OutsideImuSpan(dataset, dataset.lidar_sweeps, "lidar.csv", kLidarClockSlackNs),
                "uses the LiDAR");
  }
  if (problem.sensors.wheel) {
    const std::string outside = form == sensors::WheelForm::kAngularRates
                                    ? OutsideImuSpan(dataset, dataset.wheel, wheel_file, 0)
                                : form == sensors::WheelForm::kLinearSpeeds
                                    ? OutsideImuSpan(dataset, dataset.wheel_speeds, wheel_file, 0)
                                    : OutsideImuSpan(dataset, dataset.odometry, wheel_file, 0);
    add_outside(outside, "uses the wheel encoders");
  }
  if (problem.sensors.gnss) {
    add_outside(OutsideImuSpan(dataset, dataset.gnss, "gnss.csv", 0), "uses GNSS");
  }
  if (reasons.empty()) return;
  std::string message = reasons[0];
  for (size_t i = 1; i < reasons.size(); ++i) message += "; " + reasons[i];
  throw Error(message);
}

}  // namespace io
}  // namespace autocal
