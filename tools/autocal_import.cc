// autocal_import: a recorded ROS log (ROS 1 .bag, .mcap, rosbag2 .db3 or directory) into an
// autocal dataset directory, or a listing of its topics (docs/import.md).
//
//   autocal_import --input=BAG --output=DIR [--imu_topic=...] [--lidar_topic=...]
//       [--wheel_topic=...] [--gnss_topic=...] [--odometry_topic=...]
//       [--wheel_joints=LEFT,RIGHT] [--use_receive_time]
//   autocal_import --input=BAG --list

#include <gflags/gflags.h>

#include <iostream>

#include "autocal/common/error.h"
#include "autocal/import/import_bag.h"
#include "tool_help.h"

DEFINE_string(input, "", "ROS 1 .bag, .mcap or .db3 file, or a rosbag2 directory");
DEFINE_string(output, "", "dataset directory to create (must not exist or be empty)");
DEFINE_bool(list, false, "print each topic with its type, message count, span and rate");
DEFINE_string(imu_topic, "", "sensor_msgs/Imu topic (default: the only one)");
DEFINE_string(lidar_topic, "",
              "sensor_msgs/PointCloud2 topic (default: the only one; none = skip)");
DEFINE_string(wheel_topic, "", "sensor_msgs/JointState topic (default: the only one; none = skip)");
DEFINE_string(gnss_topic, "", "sensor_msgs/NavSatFix topic (default: the only one; none = skip)");
DEFINE_string(odometry_topic, "",
              "nav_msgs/Odometry or geometry_msgs/TwistStamped topic -> odometry.csv "
              "(default: the only one; none = skip)");
DEFINE_string(tf_static_topic, "/tf_static", "tf2_msgs/TFMessage topic of the static transforms");
DEFINE_string(wheel_joints, "",
              "LEFT,RIGHT: JointState names of the rear wheels (default: by name)");
DEFINE_string(base_frame, "base_link", "frame_id of the vehicle body, for T_I_V");
DEFINE_bool(use_receive_time, false,
            "stamp samples with the recorder's receive time, not the header");
DEFINE_double(unknown_gnss_sigma_m, 5.0,
              "1-sigma (m) for fixes without a usable covariance; <= 0 refuses them");

int main(int argc, char** argv) {
  gflags::SetUsageMessage(
      "autocal_import --input=BAG --output=DIR [--imu_topic=...] ... | --input=BAG --list");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_import")) return 0;
  gflags::ParseCommandLineFlags(&argc, &argv, true);
  try {
    if (argc > 1) throw autocal::Error(std::string("unexpected argument '") + argv[1] + "'");
    if (FLAGS_input.empty()) throw autocal::Error("--input is required");
    if (FLAGS_list) {
      std::vector<std::string> warnings;
      const auto topics = autocal::import::ListTopics(FLAGS_input, &warnings);
      std::cout << autocal::import::FormatTopicList(topics);
      for (const std::string& warning : warnings) std::cout << "warning: " << warning << "\n";
      return 0;
    }
    if (FLAGS_output.empty()) throw autocal::Error("--output (or --list) is required");
    autocal::import::ImportOptions options;
    options.input = FLAGS_input;
    options.output = FLAGS_output;
    options.imu_topic = FLAGS_imu_topic;
    options.lidar_topic = FLAGS_lidar_topic;
    options.wheel_topic = FLAGS_wheel_topic;
    options.gnss_topic = FLAGS_gnss_topic;
    options.odometry_topic = FLAGS_odometry_topic;
    options.tf_static_topic = FLAGS_tf_static_topic;
    options.base_frame = FLAGS_base_frame;
    options.use_receive_time = FLAGS_use_receive_time;
    options.unknown_gnss_sigma_m = FLAGS_unknown_gnss_sigma_m;
    if (!FLAGS_wheel_joints.empty()) {
      const size_t comma = FLAGS_wheel_joints.find(',');
      if (comma == std::string::npos || comma == 0 || comma + 1 == FLAGS_wheel_joints.size()) {
        throw autocal::Error("--wheel_joints expects LEFT,RIGHT, found '" + FLAGS_wheel_joints +
                             "'");
      }
      options.left_wheel_joint = FLAGS_wheel_joints.substr(0, comma);
      options.right_wheel_joint = FLAGS_wheel_joints.substr(comma + 1);
    }
    std::cout << autocal::import::ImportBag(options).FormatText();
  } catch (const autocal::Error& e) {
    std::cerr << "autocal_import: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
