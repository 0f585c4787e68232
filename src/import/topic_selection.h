#pragma once

// Which bag topic feeds which dataset stream: the topic the options name, else the one
// topic of the stream's message type. Private to src/import.

#include <set>
#include <string>
#include <vector>

#include "autocal/import/import_bag.h"
#include "import/bag_reader.h"
#include "import/ros_messages.h"

namespace autocal {
namespace import {

struct SelectedTopic {
  std::string topic;  // empty: not imported
  std::string type;
  MessageKind kind = MessageKind::kOther;
  Serialization serialization = Serialization::kRos1;
  std::set<uint32_t> connection_ids;

  bool selected() const { return !topic.empty(); }
  bool Has(uint32_t connection_id) const { return connection_ids.count(connection_id) != 0; }
};

struct TopicSelection {
  SelectedTopic imu, lidar, wheel, gnss, odometry, tf_static;
};

// Throws autocal::Error when a named topic is missing or of the wrong type, when a type
// has several topics and none is named (the message lists them and the flag to use), and
// when no IMU topic is found.
TopicSelection SelectTopics(const std::vector<Connection>& connections,
                            const ImportOptions& options);

}  // namespace import
}  // namespace autocal
