// Writes the seed corpus of the bag fuzz targets into <out>/<target>/: small valid ROS 1
// bags (uncompressed, bz2, lz4; indexed and not), MCAP files (no compression, lz4, zstd;
// with and without summary; unchunked), single messages of every supported type in both
// serializations, and a rosbag2 metadata.yaml. Made by the test writers of test/import.
//   autocal_fuzz_bag_seeds <out>

#include <Eigen/Geometry>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "mcap_writer.h"
#include "ros1_bag_writer.h"
#include "ros_message_writer.h"

namespace autocal {
namespace fuzz {
namespace {

using test::McapWriter;
using test::McapWriterOptions;
using test::Ros1BagWriter;

constexpr int64_t kStartNs = 1'700'000'000'000'000'000;

// A message of every supported type, in the order of import::MessageKind.
std::vector<std::string> Messages(bool cdr, int64_t stamp_ns) {
  std::string points;
  for (int i = 0; i < 3; ++i) {
    test::AppendValue<float>(&points, 1.0f + i);
    test::AppendValue<float>(&points, -0.5f * i);
    test::AppendValue<float>(&points, 0.25f);
    test::AppendValue<float>(&points, 10.0f * i);
    test::AppendValue<uint32_t>(&points, 1000u * i);
  }
  const std::vector<test::TestPointField> fields = {
      {"x", 0, 7}, {"y", 4, 7}, {"z", 8, 7}, {"intensity", 12, 7}, {"t", 16, 6}};
  return {
      test::SerializeImu(cdr, stamp_ns, "imu", {0.0, 0.01, 0.25}, {0.1, 0.0, 9.81}),
      test::SerializePointCloud2(cdr, stamp_ns, "lidar", 1, 3, fields, 20, 60, points),
      test::SerializeOdometry(cdr, stamp_ns, 3.5, 0.1),
      test::SerializeTwistStamped(cdr, stamp_ns, 3.5, 0.1),
      test::SerializeJointState(cdr, stamp_ns, {"left", "right"}, {0.1, 0.2}, {15.0, 15.5}),
      test::SerializeNavSatFix(cdr, stamp_ns, 0, 48.1, 11.5, 520.0, {0.5, 0.5, 1.0}, 2),
      test::SerializeTfMessage(
          cdr, stamp_ns, {{"base_link", "lidar", Eigen::Quaterniond::Identity(), {0.5, 0.0, 1.2}}}),
  };
}

const char* const kRos1Types[] = {"sensor_msgs/Imu",        "sensor_msgs/PointCloud2",
                                  "nav_msgs/Odometry",      "geometry_msgs/TwistStamped",
                                  "sensor_msgs/JointState", "sensor_msgs/NavSatFix",
                                  "tf2_msgs/TFMessage"};
const char* const kTopics[] = {"/imu", "/points", "/odom", "/twist", "/joints", "/fix", "/tf"};

std::string Ros1Bag(Ros1BagWriter::Options options) {
  Ros1BagWriter writer(options);
  for (int kind = 0; kind < 7; ++kind) writer.AddConnection(kTopics[kind], kRos1Types[kind]);
  for (int i = 0; i < 2; ++i) {
    const int64_t t_ns = kStartNs + i * 10'000'000;
    const std::vector<std::string> messages = Messages(false, t_ns);
    for (uint32_t kind = 0; kind < messages.size(); ++kind)
      writer.Write(kind, t_ns, messages[kind]);
  }
  return writer.Finish();
}

void WriteRos1Seeds(const std::string& dir) {
  using Compression = Ros1BagWriter::Compression;
  const struct {
    const char* name;
    Compression compression;
    bool indexed;
  } bags[] = {{"plain.bag", Compression::kNone, true},
              {"bz2.bag", Compression::kBz2, true},
              {"lz4.bag", Compression::kLz4, true},
              {"unindexed.bag", Compression::kNone, false}};
  for (const auto& bag : bags) {
    Ros1BagWriter::Options options;
    options.compression = bag.compression;
    options.indexed = bag.indexed;
    options.chunk_bytes = 1024;
    test::WriteFile(dir + "/" + bag.name, Ros1Bag(options));
  }
}

std::string Mcap(McapWriterOptions options) {
  McapWriter writer(std::move(options));
  std::vector<uint16_t> channels;
  for (int kind = 0; kind < 7; ++kind) {
    std::string ros2_type = kRos1Types[kind];  // "sensor_msgs/Imu" -> "sensor_msgs/msg/Imu"
    ros2_type.insert(ros2_type.find('/'), "/msg");
    channels.push_back(writer.AddChannel(writer.AddSchema(ros2_type), kTopics[kind]));
  }
  for (int i = 0; i < 2; ++i) {
    const int64_t t_ns = kStartNs + i * 10'000'000;
    const std::vector<std::string> messages = Messages(true, t_ns);
    for (size_t kind = 0; kind < messages.size(); ++kind) {
      writer.AddMessage(channels[kind], static_cast<uint64_t>(t_ns), messages[kind]);
    }
  }
  return writer.Finish();
}

void WriteMcapSeeds(const std::string& dir) {
  for (const char* compression : {"", "lz4", "zstd"}) {
    for (const bool summary : {true, false}) {
      McapWriterOptions options;
      options.compression = compression;
      options.summary = summary;
      const std::string name = std::string(*compression ? compression : "none") +
                               (summary ? "_summary" : "_no_summary") + ".mcap";
      test::WriteFile(dir + "/" + name, Mcap(options));
    }
  }
  McapWriterOptions unchunked;
  unchunked.chunked = false;
  test::WriteFile(dir + "/unchunked.mcap", Mcap(unchunked));
}

// Byte 0 selects the decoder (kind, bit 7 for CDR), as fuzz_ros_messages reads it.
void WriteMessageSeeds(const std::string& dir) {
  for (const bool cdr : {false, true}) {
    const std::vector<std::string> messages = Messages(cdr, kStartNs);
    for (size_t kind = 0; kind < messages.size(); ++kind) {
      const char selector = static_cast<char>(kind | (cdr ? 0x80 : 0));
      test::WriteFile(dir + "/" + std::to_string(kind) + (cdr ? "_cdr" : "_ros1"),
                      std::string(1, selector) + messages[kind]);
    }
  }
}

void WriteMetadataSeed(const std::string& dir) {
  test::WriteFile(dir + "/metadata.yaml",
                  "rosbag2_bagfile_information:\n"
                  "  version: 5\n"
                  "  storage_identifier: mcap\n"
                  "  duration:\n    nanoseconds: 9\n"
                  "  starting_time:\n    nanoseconds_since_epoch: 1000\n"
                  "  message_count: 2\n"
                  "  topics_with_message_count:\n"
                  "    - topic_metadata:\n        name: /imu\n"
                  "        type: sensor_msgs/msg/Imu\n        serialization_format: cdr\n"
                  "        offered_qos_profiles: \"\"\n      message_count: 2\n"
                  "  compression_format: \"zstd\"\n"
                  "  compression_mode: \"FILE\"\n"
                  "  relative_file_paths:\n    - bag_0.mcap.zstd\n");
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
  for (const char* target : {"ros1_bag", "mcap", "ros_messages", "rosbag2_metadata"}) {
    std::filesystem::create_directories(out + "/" + target);
  }
  WriteRos1Seeds(out + "/ros1_bag");
  WriteMcapSeeds(out + "/mcap");
  WriteMessageSeeds(out + "/ros_messages");
  WriteMetadataSeed(out + "/rosbag2_metadata");
  return 0;
}
