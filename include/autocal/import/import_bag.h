#pragma once

// Import of a recorded ROS log (a ROS 1 bag, an MCAP file, a rosbag2 SQLite file or
// directory) into an autocal dataset directory (datasets/README.md), and the listing of
// its topics. docs/import.md says which messages become which files.
//
// The bag is streamed: one chunk in memory at a time, each LiDAR sweep written as it is
// read; only the small per-sample streams (IMU, wheel, GNSS, odometry) are kept until the
// end, where they are sorted by stamp and written. The dataset is written under a
// temporary name beside the output and renamed when complete, so a failed or killed import
// never leaves a directory that looks like a dataset.

#include <cstdint>
#include <string>
#include <vector>

namespace autocal {
namespace import {

struct ImportOptions {
  std::string input;   // a .bag, .mcap or .db3 file, or a rosbag2 directory
  std::string output;  // dataset directory to create: must not exist, or be empty
  // Topic per stream: "" chooses the one topic of the stream's message type (an error when
  // several have it), "none" skips the stream.
  std::string imu_topic;       // sensor_msgs/Imu -> imu.csv (required)
  std::string lidar_topic;     // sensor_msgs/PointCloud2 -> lidar.csv, lidar/*.ply
  std::string wheel_topic;     // sensor_msgs/JointState -> wheel.csv
  std::string gnss_topic;      // sensor_msgs/NavSatFix -> gnss.csv
  std::string odometry_topic;  // nav_msgs/Odometry or geometry_msgs/TwistStamped -> odometry.csv
  std::string tf_static_topic = "/tf_static";  // tf2_msgs/TFMessage -> nominal extrinsics
  // JointState names of the left and right rear wheels; empty: by name ("left"/"right").
  std::string left_wheel_joint;
  std::string right_wheel_joint;
  // The frame_id of the vehicle body (REP-105 base_link), for T_I_V.
  std::string base_frame = "base_link";
  // Stamp every sample with the recorder's receive time instead of its header stamp.
  bool use_receive_time = false;
  // 1-sigma (m, every axis) given to fixes whose covariance_type is unknown (0) or whose
  // covariance diagonal is not positive; <= 0 refuses such fixes (an error).
  double unknown_gnss_sigma_m = 5.0;
};

// What was read from one topic and what became of it.
struct ImportedStream {
  std::string topic;  // empty when the stream was not imported
  std::string type;
  int64_t messages = 0;  // messages read on the topic
  int64_t written = 0;   // rows (or sweeps) written
};

struct ImportSummary {
  std::string output;
  ImportedStream imu, lidar, wheel, gnss, odometry;
  int64_t static_transforms = 0;
  // Plain-language lines about everything dropped, defaulted or guessed.
  std::vector<std::string> warnings;

  // A few lines for a person: each stream, its topic and counts, then the warnings.
  std::string FormatText() const;
};

// Runs the import. Throws autocal::Error (ParseError for malformed input, with the file
// and byte offset) and leaves no output directory behind.
ImportSummary ImportBag(const ImportOptions& options);

// One topic of a bag as a full read of its messages finds it (receive times).
struct TopicListing {
  std::string topic;
  std::string type;
  uint64_t message_count = 0;
  int64_t first_log_time_ns = 0;
  int64_t last_log_time_ns = 0;

  double span_s() const { return 1e-9 * static_cast<double>(last_log_time_ns - first_log_time_ns); }
  // (count - 1) / span; 0 with fewer than two messages.
  double mean_rate_hz() const;
};

// Reads every message of `input` (so a malformed bag fails here too) and lists its topics
// in name order. `warnings`, when given, receives what the read found, one sentence each
// naming the file: no index or summary (read by a linear scan), a last chunk a stopped recorder
// left open (the records read from it).
std::vector<TopicListing> ListTopics(const std::string& input,
                                     std::vector<std::string>* warnings = nullptr);
// One line per topic: topic, type, count, span (s), mean rate (Hz).
std::string FormatTopicList(const std::vector<TopicListing>& topics);

}  // namespace import
}  // namespace autocal
