// The import of ROS 2 (CDR) messages, independently of the ROS 2 containers: an in-memory
// BagReader hands ImportFromReader the messages a rosbag2 or MCAP reader would, with ROS 2
// type names ("sensor_msgs/msg/Imu") and CDR serialization.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "autocal/io/dataset.h"
#include "import/import_from_reader.h"
#include "import/ros_message_writer.h"
#include "support/test_paths.h"

namespace autocal {
namespace import {
namespace {

namespace fs = std::filesystem;
using test::AppendValue;

constexpr int64_t kStartNs = 1710000000000000000;

class MemoryBagReader final : public BagReader {
 public:
  uint32_t Add(const std::string& topic, const std::string& type) {
    const uint32_t id = static_cast<uint32_t>(connections_.size());
    connections_.push_back({id, topic, type, Serialization::kCdr});
    return id;
  }
  void Write(uint32_t id, int64_t t_ns, std::string bytes) {
    messages_.push_back({id, t_ns, std::move(bytes)});
  }

  const std::string& path() const override { return path_; }
  const std::vector<Connection>& connections() const override { return connections_; }
  std::optional<std::vector<IndexedTopic>> IndexedTopics() const override { return {}; }
  bool Next(BagMessage* message) override {
    if (next_ == messages_.size()) return false;
    const Stored& stored = messages_[next_++];
    message->connection_id = stored.id;
    message->log_time_ns = stored.t_ns;
    message->data = stored.bytes;
    message->file_offset = next_;
    return true;
  }

 private:
  struct Stored {
    uint32_t id;
    int64_t t_ns;
    std::string bytes;
  };
  std::string path_ = "memory.mcap";
  std::vector<Connection> connections_;
  std::vector<Stored> messages_;
  size_t next_ = 0;
};

// A Livox-style cloud: x, y, z float32, reflectivity as uint8 intensity, offset_time ns.
std::string LivoxCloud(int64_t stamp_ns) {
  const std::vector<test::TestPointField> fields = {
      {"x", 0, 7}, {"y", 4, 7}, {"z", 8, 7}, {"intensity", 12, 2}, {"offset_time", 13, 6}};
  std::string data;
  for (int i = 0; i < 50; ++i) {
    AppendValue<float>(&data, 3.0f + i);
    AppendValue<float>(&data, 1.0f);
    AppendValue<float>(&data, 0.5f);
    AppendValue<uint8_t>(&data, static_cast<uint8_t>(2 * i));
    AppendValue<uint32_t>(&data, static_cast<uint32_t>(i) * 1000000u);
  }
  return test::SerializePointCloud2(true, stamp_ns, "livox_frame", 1, 50, fields, 17, 17 * 50,
                                    data);
}

TEST(ImportCdrTest, RosTwoMessagesLandInTheDataset) {
  MemoryBagReader reader;
  const uint32_t tf = reader.Add("/tf_static", "tf2_msgs/msg/TFMessage");
  const uint32_t imu = reader.Add("/imu", "sensor_msgs/msg/Imu");
  const uint32_t lidar = reader.Add("/livox/lidar", "sensor_msgs/msg/PointCloud2");
  const uint32_t fix = reader.Add("/gnss/fix", "sensor_msgs/msg/NavSatFix");
  const uint32_t twist = reader.Add("/vehicle/twist", "geometry_msgs/msg/TwistStamped");
  const Eigen::Vector3d p_base_lidar(1.5, 0.0, 1.8);
  reader.Write(tf, kStartNs,
               test::SerializeTfMessage(
                   true, kStartNs,
                   {{"base_link", "imu", Eigen::Quaterniond::Identity(), {0.2, 0, 0.3}},
                    {"base_link", "livox_frame", Eigen::Quaterniond::Identity(), p_base_lidar}}));
  for (int i = 0; i < 100; ++i) {
    const int64_t t = kStartNs + i * 10000000LL;
    reader.Write(imu, t + 1000, test::SerializeImu(true, t, "imu", {0, 0, 0.1}, {0.1, 0, 9.8}));
    if (i % 10 == 0) reader.Write(lidar, t + 2000, LivoxCloud(t));
    if (i % 20 == 0) {
      reader.Write(fix, t + 3000,
                   test::SerializeNavSatFix(true, t, 0, 52.5, 13.4, 40.0, {1, 1, 4}, 1));
    }
    if (i % 5 == 0) reader.Write(twist, t + 4000, test::SerializeTwistStamped(true, t, 8.0, 0.1));
  }

  ImportOptions options;
  options.output = (test::OutputDir("out") / "dataset").string();
  fs::remove_all(options.output);
  const ImportSummary summary = ImportFromReader(&reader, options);
  EXPECT_EQ(summary.odometry.type, "geometry_msgs/msg/TwistStamped");

  const io::Dataset dataset = io::ReadDataset(options.output);
  ASSERT_EQ(dataset.imu.size(), 100u);
  EXPECT_EQ(dataset.imu[3].t_ns, kStartNs + 30000000LL);
  EXPECT_EQ(dataset.imu[3].accel_m_s2, Eigen::Vector3d(0.1, 0, 9.8));
  ASSERT_EQ(dataset.gnss.size(), 5u);
  EXPECT_EQ(dataset.gnss[0].std_enu_m, Eigen::Vector3d(1, 1, 2));
  ASSERT_EQ(dataset.lidar_sweeps.size(), 10u);
  const lidar::LidarSweep sweep = dataset.LoadSweep(2);
  ASSERT_EQ(sweep.cloud.size(), 50);
  EXPECT_NEAR(sweep.cloud.time_s[20], 0.020, 1e-9);
  EXPECT_EQ(sweep.cloud.intensity[20], 40.0f);
  EXPECT_TRUE(dataset.sensors.nominal_calibration.p_I_L.isApprox(Eigen::Vector3d(1.3, 0, 1.5)));
  EXPECT_TRUE(dataset.sensors.nominal_calibration.p_I_V.isApprox(Eigen::Vector3d(-0.2, 0, -0.3)));

  std::ifstream odometry(options.output + "/odometry.csv");
  std::string line;
  std::getline(odometry, line);
  std::getline(odometry, line);
  EXPECT_EQ(line, std::to_string(kStartNs) + ",8,0.1");
}

}  // namespace
}  // namespace import
}  // namespace autocal
