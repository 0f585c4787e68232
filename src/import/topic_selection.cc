#include "import/topic_selection.h"

#include <map>

#include "autocal/common/error.h"

namespace autocal {
namespace import {
namespace {

// One stream to fill: its flag, the message kinds it accepts and whether it is required.
struct StreamRule {
  const char* flag;
  std::vector<MessageKind> kinds;
  const char* type_names;
};

struct TopicEntry {
  std::string type;
  Serialization serialization = Serialization::kRos1;
  std::set<uint32_t> connection_ids;
};
using TopicTable = std::map<std::string, TopicEntry>;

TopicTable TopicsOf(const std::vector<Connection>& connections) {
  TopicTable table;
  for (const Connection& connection : connections) {
    TopicEntry& entry = table[connection.topic];
    if (!entry.type.empty() &&
        (entry.type != connection.type || entry.serialization != connection.serialization)) {
      throw Error("topic " + connection.topic + " carries two types or serializations: " +
                  entry.type + " and " + connection.type);
    }
    entry.type = connection.type;
    entry.serialization = connection.serialization;
    entry.connection_ids.insert(connection.id);
  }
  return table;
}

bool Accepts(const StreamRule& rule, MessageKind kind) {
  for (MessageKind k : rule.kinds) {
    if (k == kind) return true;
  }
  return false;
}

SelectedTopic Select(const TopicTable& table, const StreamRule& rule, const std::string& named) {
  SelectedTopic selected;
  if (named == "none") return selected;
  std::vector<std::string> candidates;
  if (!named.empty()) {
    const auto it = table.find(named);
    if (it == table.end()) {
      throw Error("--" + std::string(rule.flag) + "=" + named + ": the bag has no such topic");
    }
    if (!Accepts(rule, KindOfType(it->second.type))) {
      throw Error("--" + std::string(rule.flag) + "=" + named + ": the topic's type is " +
                  it->second.type + ", expected " + rule.type_names);
    }
    candidates.push_back(named);
  } else {
    for (const auto& [topic, entry] : table) {
      if (Accepts(rule, KindOfType(entry.type))) candidates.push_back(topic);
    }
  }
  if (candidates.empty()) return selected;
  if (candidates.size() > 1) {
    std::string list;
    for (const std::string& topic : candidates) list += (list.empty() ? "" : ", ") + topic;
    throw Error(std::string("several topics of type ") + rule.type_names + " (" + list +
                "): choose one with --" + rule.flag + "=TOPIC (or --" + rule.flag + "=none)");
  }
  const auto& entry = table.at(candidates.front());
  selected.topic = candidates.front();
  selected.type = entry.type;
  selected.kind = KindOfType(entry.type);
  selected.serialization = entry.serialization;
  selected.connection_ids = entry.connection_ids;
  return selected;
}

}  // namespace

TopicSelection SelectTopics(const std::vector<Connection>& connections,
                            const ImportOptions& options) {
  const TopicTable table = TopicsOf(connections);
  TopicSelection selection;
  selection.imu =
      Select(table, {"imu_topic", {MessageKind::kImu}, "sensor_msgs/Imu"}, options.imu_topic);
  if (!selection.imu.selected()) {
    throw Error("the bag has no sensor_msgs/Imu topic" +
                std::string(options.imu_topic == "none" ? " selected" : "") +
                ": every dataset needs imu.csv");
  }
  selection.lidar =
      Select(table, {"lidar_topic", {MessageKind::kPointCloud2}, "sensor_msgs/PointCloud2"},
             options.lidar_topic);
  selection.wheel =
      Select(table, {"wheel_topic", {MessageKind::kJointState}, "sensor_msgs/JointState"},
             options.wheel_topic);
  selection.gnss = Select(table, {"gnss_topic", {MessageKind::kNavSatFix}, "sensor_msgs/NavSatFix"},
                          options.gnss_topic);
  selection.odometry = Select(table,
                              {"odometry_topic",
                               {MessageKind::kOdometry, MessageKind::kTwistStamped},
                               "nav_msgs/Odometry or geometry_msgs/TwistStamped"},
                              options.odometry_topic);
  // /tf_static is looked up by name only: /tf carries the same type with moving frames.
  const auto tf = table.find(options.tf_static_topic);
  if (!options.tf_static_topic.empty() && options.tf_static_topic != "none" && tf != table.end() &&
      KindOfType(tf->second.type) == MessageKind::kTfMessage) {
    selection.tf_static.topic = tf->first;
    selection.tf_static.type = tf->second.type;
    selection.tf_static.kind = MessageKind::kTfMessage;
    selection.tf_static.serialization = tf->second.serialization;
    selection.tf_static.connection_ids = tf->second.connection_ids;
  }
  return selection;
}

}  // namespace import
}  // namespace autocal
