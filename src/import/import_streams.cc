#include "import/import_streams.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>

#include "autocal/common/error.h"
#include "autocal/io/sensors_yaml.h"
#include "autocal/sensors/sample_timing.h"
#include "import/ros_messages.h"
#include "io/text_format.h"

namespace autocal {
namespace import {
namespace {

std::string Lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

// Sorts by stamp and drops samples whose stamp repeats; returns how many were dropped.
template <typename T>
int64_t SortUnique(std::vector<T>* samples) {
  std::stable_sort(samples->begin(), samples->end(),
                   [](const T& a, const T& b) { return a.t_ns < b.t_ns; });
  const auto end = std::unique(samples->begin(), samples->end(),
                               [](const T& a, const T& b) { return a.t_ns == b.t_ns; });
  const int64_t dropped = samples->end() - end;
  samples->erase(end, samples->end());
  return dropped;
}

// The rate sensors.yaml states for strictly increasing stamps: 1 / the mean interval without
// outages (sensors::MeasureTiming: a 10 Hz receiver with outages is a 10 Hz receiver), to six
// significant digits (a rate, not a nanosecond's rounding: 50 Hz, not 49.99999999999999);
// 0 with fewer than two stamps.
double RateHz(const std::vector<int64_t>& stamps_ns, const std::string& what) {
  if (stamps_ns.size() < 2) return 0.0;
  const double rate = sensors::MeasureTiming(stamps_ns, what).rate_hz();
  char digits[32];
  std::snprintf(digits, sizeof(digits), "%.6g", rate);
  return std::strtod(digits, nullptr);
}

// The one joint whose name says `side`, preferring a rear one when several do.
int FindWheelJoint(const std::vector<std::string>& names, const std::string& side,
                   const std::string& named) {
  std::vector<int> candidates;
  for (size_t i = 0; i < names.size(); ++i) {
    const bool match =
        named.empty() ? Lower(names[i]).find(side) != std::string::npos : names[i] == named;
    if (match) candidates.push_back(static_cast<int>(i));
  }
  if (candidates.size() > 1) {
    std::vector<int> rear;
    for (int i : candidates) {
      const std::string name = Lower(names[i]);
      if (name.find("rear") != std::string::npos || name.find("back") != std::string::npos) {
        rear.push_back(i);
      }
    }
    candidates = rear;
  }
  return candidates.size() == 1 ? candidates.front() : -1;
}

// A JointState's two wheel values out of `values`: nullopt when it has too few.
std::optional<Eigen::Vector2d> WheelPair(const std::vector<double>& values, int left, int right) {
  if (values.size() <= static_cast<size_t>(std::max(left, right))) return std::nullopt;
  return Eigen::Vector2d(values[left], values[right]);
}

// Why a stream's rate (RateHz of its stamps) cannot be stated in sensors.yaml: "N samples over
// S s (R Hz), not a stream at the ... Hz sensors.yaml can state", or "1 sample, ...".
std::string WhyNoStatedRate(const std::vector<int64_t>& stamps_ns, double rate_hz, const char* what,
                            const io::RateRangeHz& range) {
  std::string text = std::to_string(stamps_ns.size()) + " " + what;
  if (stamps_ns.size() >= 2) {
    text += " over " +
            io::internal::FormatDouble(1e-9 *
                                       static_cast<double>(stamps_ns.back() - stamps_ns.front())) +
            " s (" + io::internal::FormatDouble(rate_hz) + " Hz)";
  }
  return text + ", not a stream at the " + io::internal::FormatDouble(range.min) + " to " +
         io::internal::FormatDouble(range.max) + " Hz sensors.yaml can state";
}

std::string JoinNames(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& name : names) out += (out.empty() ? "" : ", ") + name;
  return out;
}

}  // namespace

StreamImporter::StreamImporter(const ImportOptions& options, const TopicSelection& selection,
                               io::DatasetWriter* writer, ImportSummary* summary)
    : options_(options), selection_(selection), writer_(writer), summary_(summary) {}

int64_t StreamImporter::Stamp(int64_t header_ns, int64_t log_ns) {
  if (options_.use_receive_time) return log_ns;
  if (header_ns == 0) {
    ++zero_stamps_;
    return log_ns;
  }
  return header_ns;
}

void StreamImporter::Add(const std::string& bag_path, const BagMessage& message) {
  const SelectedTopic* topics[] = {&selection_.imu,  &selection_.lidar,    &selection_.wheel,
                                   &selection_.gnss, &selection_.odometry, &selection_.tf_static};
  const SelectedTopic* topic = nullptr;
  for (const SelectedTopic* candidate : topics) {
    if (candidate->Has(message.connection_id)) topic = candidate;
  }
  if (topic == nullptr) return;
  context_.location = MessageLocation(bag_path, message);
  context_.type = NormalizedTypeName(topic->type);
  context_.topic = topic->topic;
  MessageCursor cursor(message.data, topic->serialization, &context_);
  const int64_t log_ns = message.log_time_ns;
  if (topic == &selection_.imu) {
    AddImu(&cursor, log_ns);
  } else if (topic == &selection_.lidar) {
    AddCloud(&cursor, log_ns);
  } else if (topic == &selection_.wheel) {
    AddJointState(&cursor, log_ns);
  } else if (topic == &selection_.gnss) {
    AddFix(&cursor, log_ns);
  } else if (topic == &selection_.odometry) {
    AddOdometry(&cursor, log_ns);
  } else {
    transforms_.Add(DecodeTfMessage(&cursor));
    ++summary_->static_transforms;
  }
}

void StreamImporter::AddImu(MessageCursor* cursor, int64_t log_ns) {
  const ImuMessage imu = DecodeImu(cursor);
  ++summary_->imu.messages;
  if (imu_frame_.empty()) imu_frame_ = imu.frame_id;
  if (!imu.angular_velocity_rad_s.allFinite() || !imu.linear_acceleration_m_s2.allFinite()) {
    ++non_finite_imu_;
    return;
  }
  sensors::ImuSample sample;
  sample.t_ns = Stamp(imu.stamp_ns, log_ns);
  sample.gyro_rad_s = imu.angular_velocity_rad_s;
  sample.accel_m_s2 = imu.linear_acceleration_m_s2;
  imu_.push_back(sample);
}

void StreamImporter::AddCloud(MessageCursor* cursor, int64_t log_ns) {
  PointCloudMessage cloud = DecodePointCloud2(cursor);
  ++summary_->lidar.messages;
  if (lidar_frame_.empty()) lidar_frame_ = cloud.frame_id;
  if (cloud.height > 1) lidar_rows_ = cloud.height;
  dropped_points_ += cloud.dropped_points;
  if (cloud.time_form == PointTimeForm::kNone && !warned_no_point_time_) {
    warned_no_point_time_ = true;
    Warn(selection_.lidar.topic +
         ": the clouds have no per-point time field (t, time, timestamp, offset_time): every "
         "point gets t = 0, so the sweeps cannot be deskewed");
  }
  lidar::LidarSweep sweep;
  sweep.t_ns = Stamp(cloud.stamp_ns, log_ns);
  if (cloud.cloud.empty()) {
    ++empty_sweeps_;
    return;
  }
  if (!sweep_stamps_.empty() && sweep.t_ns <= last_sweep_ns_) {
    ++unordered_sweeps_;
    return;
  }
  sweep.cloud = std::move(cloud.cloud);
  writer_->AddSweep(sweep);
  last_sweep_ns_ = sweep.t_ns;
  sweep_stamps_.push_back(sweep.t_ns);
  ++summary_->lidar.written;
}

std::pair<int, int> StreamImporter::WheelJoints(const std::vector<std::string>& names) {
  if (names == joint_names_) return joint_indices_;
  const int left = FindWheelJoint(names, "left", options_.left_wheel_joint);
  const int right = FindWheelJoint(names, "right", options_.right_wheel_joint);
  const bool named = !options_.left_wheel_joint.empty() || !options_.right_wheel_joint.empty();
  if ((left < 0 || right < 0) && !named && names.size() >= 2) {
    throw Error(selection_.wheel.topic +
                ": cannot tell the left and right rear wheels among "
                "the joints [" +
                JoinNames(names) +
                "]: name them with "
                "--wheel_joints=LEFT,RIGHT (or skip them with --wheel_topic=none)");
  }
  joint_names_ = names;
  joint_indices_ = {left, right};
  return joint_indices_;
}

std::optional<Eigen::Vector2d> StreamImporter::RatesFromAngles(int64_t t_ns,
                                                               const Eigen::Vector2d& angles_rad,
                                                               int64_t* midway_ns,
                                                               bool* unordered) {
  *unordered = has_previous_angles_ && t_ns <= previous_angles_ns_;
  if (*unordered) return std::nullopt;  // the angles go on from the last message in order
  const bool usable = has_previous_angles_;
  const double dt_s = 1e-9 * static_cast<double>(t_ns - previous_angles_ns_);
  const Eigen::Vector2d rates = (angles_rad - previous_angles_rad_) / dt_s;
  *midway_ns = previous_angles_ns_ + (t_ns - previous_angles_ns_) / 2;
  has_previous_angles_ = true;
  previous_angles_ns_ = t_ns;
  previous_angles_rad_ = angles_rad;
  if (!usable) return std::nullopt;
  return rates;
}

void StreamImporter::AddJointState(MessageCursor* cursor, int64_t log_ns) {
  const JointStateMessage joints = DecodeJointState(cursor);
  ++summary_->wheel.messages;
  const auto [left, right] = WheelJoints(joints.names);
  if (left < 0 || right < 0) {
    ++joint_states_without_wheels_;
    return;
  }
  const int64_t t_ns = Stamp(joints.stamp_ns, log_ns);
  const std::optional<Eigen::Vector2d> velocities = WheelPair(joints.velocity_rad_s, left, right);
  const std::optional<Eigen::Vector2d> angles = WheelPair(joints.position_rad, left, right);
  // The rates from the angles whenever the angles are finite: the next message may need this
  // one's as its reference (a driver that fills NaN for a velocity it does not know).
  std::optional<Eigen::Vector2d> from_angles;
  int64_t midway_ns = 0;
  bool unordered = false;
  if (angles && angles->allFinite()) {
    from_angles = RatesFromAngles(t_ns, *angles, &midway_ns, &unordered);
  }
  sensors::WheelSample sample;
  if (velocities && velocities->allFinite()) {
    sample.t_ns = t_ns;
    sample.left_rad_s = (*velocities)(0);
    sample.right_rad_s = (*velocities)(1);
  } else if (from_angles) {
    sample.t_ns = midway_ns;
    sample.left_rad_s = (*from_angles)(0);
    sample.right_rad_s = (*from_angles)(1);
  } else {
    if (unordered) {
      ++unordered_joint_positions_;
    } else if (!(angles && angles->allFinite())) {
      ++((velocities || angles) ? non_finite_joint_states_ : joint_states_without_wheels_);
    }
    return;  // else the first angles: the reference for the next message
  }
  wheel_.push_back(sample);
}

void StreamImporter::AddFix(MessageCursor* cursor, int64_t log_ns) {
  const NavSatFixMessage fix = DecodeNavSatFix(cursor);
  ++summary_->gnss.messages;
  if (gnss_frame_.empty()) gnss_frame_ = fix.frame_id;
  if (fix.status < 0) {
    ++no_fix_;
    return;
  }
  // NaN marks a coordinate the receiver did not give (nmea_navsat_driver: the altitude of
  // every RMC fix); such a fix is dropped, whatever its covariance.
  if (!std::isfinite(fix.latitude_deg) || !std::isfinite(fix.longitude_deg) ||
      !std::isfinite(fix.altitude_m)) {
    ++non_finite_fix_;
    return;
  }
  sensors::GnssFix out;
  out.t_ns = Stamp(fix.stamp_ns, log_ns);
  out.lat_deg = fix.latitude_deg;
  out.lon_deg = fix.longitude_deg;
  out.alt_m = fix.altitude_m;
  const auto& c = fix.position_covariance_m2;
  const Eigen::Vector3d variance(c[0], c[4], c[8]);  // east, north, up
  if (fix.covariance_type != 0 && (variance.array() > 0.0).all() && variance.allFinite()) {
    out.std_enu_m = variance.cwiseSqrt();
  } else {
    if (options_.unknown_gnss_sigma_m <= 0.0) {
      cursor->Fail("NavSatFix covariance is " +
                   std::string(fix.covariance_type == 0 ? "of unknown type" : "not positive") +
                   " and no default sigma is set (give one with --unknown_gnss_sigma_m)");
    }
    out.std_enu_m.setConstant(options_.unknown_gnss_sigma_m);
    ++defaulted_gnss_sigma_;
  }
  gnss_.push_back(out);
}

void StreamImporter::AddOdometry(MessageCursor* cursor, int64_t log_ns) {
  const VehicleTwistMessage twist = selection_.odometry.kind == MessageKind::kOdometry
                                        ? DecodeOdometry(cursor)
                                        : DecodeTwistStamped(cursor);
  ++summary_->odometry.messages;
  if (!std::isfinite(twist.speed_m_s) || !std::isfinite(twist.yaw_rate_rad_s)) {
    ++non_finite_odometry_;
    return;
  }
  odometry_.push_back({Stamp(twist.stamp_ns, log_ns), twist.speed_m_s, twist.yaw_rate_rad_s});
}

void StreamImporter::MeasureRates() {
  // RateHz is 0 for fewer than two stamps, which no range contains.
  const std::vector<int64_t> imu_stamps = sensors::StampsOf(imu_);
  rates_.imu = RateHz(imu_stamps, selection_.imu.topic);
  if (!io::kImuRateRangeHz.Contains(rates_.imu)) {
    throw Error(selection_.imu.topic + ": " +
                WhyNoStatedRate(imu_stamps, rates_.imu, "IMU samples", io::kImuRateRangeHz));
  }
  // An optional stream without a rate is left out, with a warning, not the whole import.
  const auto optional = [&](const std::vector<int64_t>& stamps, const io::RateRangeHz& range,
                            const SelectedTopic& topic, const char* what) {
    if (stamps.empty()) return 0.0;
    const double rate_hz = RateHz(stamps, topic.topic);
    if (range.Contains(rate_hz)) return rate_hz;
    Warn(topic.topic +
         ": left out of the dataset: " + WhyNoStatedRate(stamps, rate_hz, what, range));
    return 0.0;
  };
  const auto optional_samples = [&](auto* samples, const io::RateRangeHz& range,
                                    const SelectedTopic& topic, const char* what) {
    const double rate = optional(sensors::StampsOf(*samples), range, topic, what);
    if (rate == 0.0) samples->clear();
    return rate;
  };
  rates_.lidar = optional(sweep_stamps_, io::kLidarRateRangeHz, selection_.lidar, "sweeps");
  if (rates_.lidar == 0.0) {
    sweep_stamps_.clear();
    summary_->lidar.written = 0;  // ImportBag removes the sweeps written
  }
  rates_.wheel =
      optional_samples(&wheel_, io::kWheelRateRangeHz, selection_.wheel, "wheel samples");
  rates_.odometry =
      optional_samples(&odometry_, io::kWheelRateRangeHz, selection_.odometry, "odometry samples");
  rates_.gnss = optional_samples(&gnss_, io::kGnssRateRangeHz, selection_.gnss, "GNSS fixes");
}

io::SensorsConfig StreamImporter::MakeSensorsConfig() {
  io::SensorsConfig config;
  config.imu.noise.update_rate_hz = rates_.imu;
  Warn(
      "sensors.yaml: the IMU noise densities and random walks are placeholders (EuRoC-class "
      "MEMS): replace them with your IMU's values");
  if (!sweep_stamps_.empty()) {
    sensors::LidarConfig lidar;
    lidar.rate_hz = rates_.lidar;
    if (lidar_rows_ > 1) lidar.num_beams = static_cast<int>(lidar_rows_);
    config.lidar = lidar;
  }
  if (!wheel_.empty()) {
    sensors::WheelConfig wheel;
    wheel.rate_hz = rates_.wheel;
    config.wheel = wheel;
  } else if (!odometry_.empty()) {
    // Without wheel rates the controller's twist is the wheel data (form speed_yaw_rate);
    // beside wheel rates, odometry.csv stays in the dataset, unused.
    sensors::WheelConfig wheel;
    wheel.form = sensors::WheelForm::kSpeedYawRate;
    wheel.rate_hz = rates_.odometry;
    config.wheel = wheel;
    Warn("sensors.yaml: wheel data from " + selection_.odometry.topic +
         " (form speed_yaw_rate); its noise and the controller's wheel separation "
         "(controller_track_m) are not in the bag: set them for your platform");
  }
  if (!gnss_.empty()) {
    sensors::GnssConfig gnss;
    gnss.rate_hz = rates_.gnss;
    config.gnss = gnss;
  }
  config.nominal_calibration = NominalCalibration();
  return config;
}

// The nominal extrinsics from /tf_static, by the messages' frame_ids.
sensors::Calibration StreamImporter::NominalCalibration() {
  sensors::Calibration nominal;
  const auto describe = [&](const char* what, const std::string& a, const std::string& b) {
    Warn(std::string("sensors.yaml: no static transform between '") + a + "' and '" + b + "' in " +
         (selection_.tf_static.selected() ? selection_.tf_static.topic : "the bag") + ": nominal " +
         what + " left at its default");
  };
  if (!lidar_frame_.empty()) {
    if (const auto T_I_L = transforms_.Find(imu_frame_, lidar_frame_)) {
      nominal.q_I_L = T_I_L->q;
      nominal.p_I_L = T_I_L->p;
    } else {
      describe("T_I_L", imu_frame_, lidar_frame_);
    }
  }
  if (const auto T_I_V = transforms_.Find(imu_frame_, options_.base_frame)) {
    nominal.q_I_V = T_I_V->q;
    nominal.p_I_V = T_I_V->p;
  } else {
    describe("T_I_V", imu_frame_, options_.base_frame);
  }
  if (!gnss_frame_.empty() && !gnss_.empty()) {
    if (const auto T_I_A = transforms_.Find(imu_frame_, gnss_frame_)) {
      nominal.p_I_A = T_I_A->p;
    } else {
      describe("p_I_A", imu_frame_, gnss_frame_);
    }
  }
  return nominal;
}

void StreamImporter::Finish(const std::string& /*directory: the writer's*/) {
  if (imu_.empty()) {
    throw Error(selection_.imu.topic +
                (summary_->imu.messages == 0
                     ? ": no IMU messages in the bag"
                     : ": none of its " + std::to_string(summary_->imu.messages) +
                           " IMU messages has finite values"));
  }
  const auto count = [](int64_t n, const std::string& what) {
    return std::to_string(n) + " " + what;
  };
  if (const int64_t n = SortUnique(&imu_))
    Warn(count(n, "IMU samples with a repeated stamp dropped"));
  if (const int64_t n = SortUnique(&wheel_))
    Warn(count(n, "wheel samples with a repeated stamp dropped"));
  if (const int64_t n = SortUnique(&gnss_))
    Warn(count(n, "GNSS fixes with a repeated stamp dropped"));
  if (const int64_t n = SortUnique(&odometry_))
    Warn(count(n, "odometry samples with a repeated stamp dropped"));
  if (zero_stamps_ > 0)
    Warn(count(zero_stamps_, "messages with a zero header stamp took their receive time"));
  if (unordered_sweeps_ > 0)
    Warn(count(unordered_sweeps_,
               "sweeps whose stamp did not follow the previous sweep's were dropped"));
  if (empty_sweeps_ > 0) Warn(count(empty_sweeps_, "sweeps without a valid point were dropped"));
  if (dropped_points_ > 0)
    Warn(count(dropped_points_,
               "LiDAR points without a return (non-finite or 0, 0, 0) were dropped"));
  if (unordered_joint_positions_ > 0) {
    Warn(count(unordered_joint_positions_,
               "JointState messages (positions only) whose stamp did not follow the previous "
               "one's were dropped: their angle differences would have no interval"));
  }
  if (no_fix_ > 0) Warn(count(no_fix_, "GNSS messages without a fix (status < 0) were dropped"));
  if (non_finite_fix_ > 0) {
    Warn(count(non_finite_fix_,
               "GNSS fixes with a non-finite latitude, longitude or altitude were dropped (NaN "
               "marks a coordinate the receiver did not give: an NMEA RMC fix has no altitude)"));
  }
  if (defaulted_gnss_sigma_ > 0) {
    Warn(count(defaulted_gnss_sigma_, "GNSS fixes without a usable covariance got sigma ") +
         io::internal::FormatDouble(options_.unknown_gnss_sigma_m) + " m");
  }
  if (joint_states_without_wheels_ > 0) {
    Warn(count(joint_states_without_wheels_,
               "JointState messages without both wheels' rates were skipped"));
  }

  if (non_finite_imu_ > 0) {
    Warn(count(non_finite_imu_,
               "IMU messages with a non-finite angular velocity or linear "
               "acceleration were dropped"));
  }
  if (non_finite_joint_states_ > 0) {
    Warn(count(non_finite_joint_states_,
               "JointState messages with non-finite wheel rates (and no finite wheel angles to "
               "take them from) were dropped"));
  }
  if (non_finite_odometry_ > 0) {
    Warn(count(non_finite_odometry_,
               "odometry messages with a non-finite speed or yaw rate were dropped"));
  }
  MeasureRates();

  writer_->WriteImu(imu_);
  summary_->imu.written = static_cast<int64_t>(imu_.size());
  if (!wheel_.empty()) writer_->WriteWheel(wheel_);
  summary_->wheel.written = static_cast<int64_t>(wheel_.size());
  if (!gnss_.empty()) writer_->WriteGnss(gnss_);
  summary_->gnss.written = static_cast<int64_t>(gnss_.size());
  if (!odometry_.empty()) writer_->WriteOdometry(odometry_);
  summary_->odometry.written = static_cast<int64_t>(odometry_.size());
  writer_->WriteSensorsConfig(MakeSensorsConfig());
}

}  // namespace import
}  // namespace autocal
