// The importer on the two real ROS 1 bags in shared/data/ros1_bags (bz2 chunks, recorded
// on Clearpath robots; see the README there). The listing must agree with the bags' own
// index, and the imported values with facts that do not come from the reader: the rates
// and length the README states, gravity's norm and axis at rest, and the record times a
// separate parse of the files found.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>

#include "autocal/import/import_bag.h"
#include "autocal/io/dataset.h"
#include "import/bag_reader.h"
#include "support/test_paths.h"

namespace autocal {
namespace import {
namespace {

namespace fs = std::filesystem;

fs::path BagPath(const std::string& name) { return test::SharedDataDir("ros1_bags") / name; }

// Options that import the shared bag `bag` into a fresh output directory `output` (a previous
// run's output removed).
ImportOptions FreshImport(const std::string& bag, const std::string& output) {
  ImportOptions options;
  options.input = BagPath(bag).string();
  options.output = (test::OutputDir("out") / output).string();
  fs::remove_all(options.output);
  return options;
}

const TopicListing& Find(const std::vector<TopicListing>& topics, const std::string& name) {
  for (const TopicListing& topic : topics) {
    if (topic.topic == name) return topic;
  }
  throw std::runtime_error("no topic " + name);
}

// --list reads every message; the bag's index (chunk infos, index data records) must say
// the same per topic.
void ExpectListingMatchesIndex(const std::string& path) {
  const std::vector<TopicListing> topics = ListTopics(path);
  const std::unique_ptr<BagReader> reader = OpenBag(path);
  const auto indexed = reader->IndexedTopics();
  ASSERT_TRUE(indexed.has_value());
  std::map<std::string, IndexedTopic> by_topic;
  for (const IndexedTopic& entry : *indexed) {
    for (const Connection& c : reader->connections()) {
      if (c.id != entry.connection_id) continue;
      IndexedTopic& sum = by_topic[c.topic];
      if (sum.message_count == 0 || entry.first_log_time_ns < sum.first_log_time_ns)
        sum.first_log_time_ns = entry.first_log_time_ns;
      sum.last_log_time_ns = std::max(sum.last_log_time_ns, entry.last_log_time_ns);
      sum.message_count += entry.message_count;
    }
  }
  ASSERT_EQ(by_topic.size(), topics.size());
  for (const TopicListing& topic : topics) {
    SCOPED_TRACE(topic.topic);
    EXPECT_EQ(topic.message_count, by_topic.at(topic.topic).message_count);
    EXPECT_EQ(topic.first_log_time_ns, by_topic.at(topic.topic).first_log_time_ns);
    EXPECT_EQ(topic.last_log_time_ns, by_topic.at(topic.topic).last_log_time_ns);
  }
}

TEST(RealBagsTest, Test1ListingAgreesWithItsIndexAndTheReadme) {
  AUTOCAL_REQUIRE_SHARED_DATA(BagPath("test1.bag"));
  const std::string path = BagPath("test1.bag").string();
  ExpectListingMatchesIndex(path);
  const std::vector<TopicListing> topics = ListTopics(path);
  ASSERT_EQ(topics.size(), 3u);
  const TopicListing& imu = Find(topics, "/imu/data");
  const TopicListing& odom = Find(topics, "/husky_velocity_controller/odom");
  const TopicListing& fix = Find(topics, "/fix");
  EXPECT_EQ(imu.type, "sensor_msgs/Imu");
  EXPECT_EQ(odom.type, "nav_msgs/Odometry");
  EXPECT_EQ(fix.type, "sensor_msgs/NavSatFix");
  // README: IMU 30 Hz, odometry 10 Hz, GPS 2.5 Hz, 395.3 s.
  EXPECT_NEAR(imu.mean_rate_hz(), 30.0, 0.1);
  EXPECT_NEAR(odom.mean_rate_hz(), 10.0, 0.05);
  EXPECT_NEAR(fix.mean_rate_hz(), 2.5, 0.01);
  EXPECT_NEAR(odom.span_s(), 395.3, 0.1);
  // Record times of the first and last IMU message, as a separate parse of the file finds.
  EXPECT_EQ(imu.first_log_time_ns, 1432235498025043042);
  EXPECT_EQ(imu.last_log_time_ns, 1432235893302031381);
  EXPECT_EQ(imu.message_count, 11865u);
  EXPECT_EQ(fix.message_count, 989u);
}

TEST(RealBagsTest, Test2ListingAgreesWithItsIndexAndTheReadme) {
  AUTOCAL_REQUIRE_SHARED_DATA(BagPath("test2.bag"));
  const std::string path = BagPath("test2.bag").string();
  ExpectListingMatchesIndex(path);
  const std::vector<TopicListing> topics = ListTopics(path);
  ASSERT_EQ(topics.size(), 2u);
  const TopicListing& imu = Find(topics, "/imu/data");
  const TopicListing& odom = Find(topics, "/jackal_velocity_controller/odom");
  // README: IMU 50 Hz, odometry 50 Hz, 61.2 s.
  EXPECT_NEAR(imu.mean_rate_hz(), 50.0, 0.1);
  EXPECT_NEAR(odom.mean_rate_hz(), 50.0, 0.1);
  EXPECT_NEAR(imu.span_s(), 61.2, 0.05);
}

// Odometry rows of odometry.csv where the robot stands still (speed and yaw rate ~0).
std::vector<int64_t> RestStamps(const std::string& odometry_csv) {
  std::ifstream in(odometry_csv);
  std::string line;
  std::getline(in, line);
  std::vector<int64_t> rest;
  while (std::getline(in, line)) {
    const size_t a = line.find(',');
    const size_t b = line.find(',', a + 1);
    const double speed = std::stod(line.substr(a + 1, b - a - 1));
    const double yaw_rate = std::stod(line.substr(b + 1));
    if (std::abs(speed) < 0.01 && std::abs(yaw_rate) < 0.01) {
      rest.push_back(std::stoll(line.substr(0, a)));
    }
  }
  return rest;
}

TEST(RealBagsTest, Test1ImportsIntoADatasetWithGravityOnPlusY) {
  AUTOCAL_REQUIRE_SHARED_DATA(BagPath("test1.bag"));
  const ImportOptions options = FreshImport("test1.bag", "test1");
  const ImportSummary summary = ImportBag(options);
  EXPECT_EQ(summary.odometry.topic, "/husky_velocity_controller/odom");

  const io::Dataset dataset = io::ReadDataset(options.output);  // no format error
  ASSERT_EQ(dataset.imu.size(), 11865u);
  // Every /fix message has status >= 0 (a separate parse finds status 1 throughout).
  EXPECT_EQ(dataset.gnss.size(), 989u);
  EXPECT_GT(dataset.gnss.front().std_enu_m.minCoeff(), 0.0);
  // Header stamps lie shortly before the record times.
  EXPECT_LE(dataset.imu.front().t_ns, 1432235498025043042);
  EXPECT_GE(dataset.imu.front().t_ns, 1432235498025043042 - 100000000);
  EXPECT_LE(dataset.imu.back().t_ns, 1432235893302031381);
  EXPECT_GE(dataset.imu.back().t_ns, 1432235893302031381 - 100000000);

  // Gravity at rest: IMU samples within 50 ms of a standing-still odometry row.
  const std::vector<int64_t> rest = RestStamps(options.output + "/odometry.csv");
  ASSERT_GT(rest.size(), 50u) << "test1 stands still for ~11 s";
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int count = 0;
  size_t r = 0;
  for (const sensors::ImuSample& sample : dataset.imu) {
    while (r < rest.size() && rest[r] < sample.t_ns - 50000000) ++r;
    if (r < rest.size() && std::abs(rest[r] - sample.t_ns) <= 50000000) {
      sum += sample.accel_m_s2;
      ++count;
    }
  }
  ASSERT_GT(count, 100);
  const Eigen::Vector3d mean = sum / count;
  EXPECT_NEAR(mean.norm(), 9.8, 0.1) << mean.transpose();
  Eigen::Index axis = 0;
  mean.cwiseAbs().maxCoeff(&axis);
  EXPECT_EQ(axis, 1) << mean.transpose();
  EXPECT_GT(mean.y(), 9.5) << mean.transpose();
}

// The Husky logs no wheel rates, only its controller's twist: the imported dataset's wheel
// data are that twist (form speed_yaw_rate) at the rate the README states.
TEST(RealBagsTest, Test1ImportsTheControllerTwistAsItsWheelData) {
  AUTOCAL_REQUIRE_SHARED_DATA(BagPath("test1.bag"));
  const ImportOptions options = FreshImport("test1.bag", "test1_form");
  const ImportSummary summary = ImportBag(options);
  const io::Dataset dataset = io::ReadDataset(options.output);
  ASSERT_TRUE(dataset.sensors.wheel.has_value());
  EXPECT_EQ(dataset.wheel_form(), sensors::WheelForm::kSpeedYawRate);
  EXPECT_NEAR(dataset.sensors.wheel->rate_hz, 10.0, 0.05);
  EXPECT_FALSE(dataset.sensors.wheel->controller_track_m.has_value());
  EXPECT_TRUE(dataset.wheel.empty());
  EXPECT_EQ(static_cast<int64_t>(dataset.odometry.size()), summary.odometry.written);
  EXPECT_EQ(dataset.wheel_sample_count(), dataset.odometry.size());
  EXPECT_NEAR(
      1e-9 * static_cast<double>(dataset.odometry.back().t_ns - dataset.odometry.front().t_ns),
      395.3, 0.2);
  // A Husky drives at most about 1 m/s.
  double max_speed_m_s = 0.0;
  for (const sensors::OdometrySample& s : dataset.odometry)
    max_speed_m_s = std::max(max_speed_m_s, std::abs(s.speed_m_s));
  EXPECT_GT(max_speed_m_s, 0.3);
  EXPECT_LT(max_speed_m_s, 1.1);
}

// sensors.yaml states each measured rate to six significant digits: the Jackal's controller
// twist, 3059 intervals over 61.18 s, is 50 Hz, not the division's 49.99999999999999.
TEST(RealBagsTest, Test2StatesItsMeasuredRatesToSixDigits) {
  AUTOCAL_REQUIRE_SHARED_DATA(BagPath("test2.bag"));
  const ImportOptions options = FreshImport("test2.bag", "test2_rates");
  ImportBag(options);
  const io::Dataset dataset = io::ReadDataset(options.output);
  ASSERT_TRUE(dataset.sensors.wheel.has_value());
  EXPECT_EQ(dataset.sensors.wheel->rate_hz, 50.0);
  EXPECT_EQ(dataset.sensors.imu.noise.update_rate_hz, 50.0);
  std::ifstream file(fs::path(options.output) / "sensors.yaml");
  const std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  EXPECT_THAT(text, ::testing::HasSubstr("  rate_hz: 50\n"));
  EXPECT_THAT(text, ::testing::Not(::testing::HasSubstr("99999")));
}

}  // namespace
}  // namespace import
}  // namespace autocal
