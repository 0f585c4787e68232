// ListTopics / FormatTopicList and ImportSummary::FormatText.

#include <cstdio>
#include <map>

#include "autocal/common/format.h"
#include "autocal/import/import_bag.h"
#include "import/bag_reader.h"

namespace autocal {
namespace import {

std::vector<TopicListing> ListTopics(const std::string& input, std::vector<std::string>* warnings) {
  const std::unique_ptr<BagReader> reader = OpenBag(input);
  std::map<uint32_t, std::string> topic_of;
  std::map<std::string, TopicListing> topics;
  for (const Connection& connection : reader->connections()) {
    topic_of[connection.id] = connection.topic;
    TopicListing& listing = topics[connection.topic];
    listing.topic = connection.topic;
    listing.type = connection.type;
  }
  BagMessage message;
  while (reader->Next(&message)) {
    TopicListing& listing = topics[topic_of[message.connection_id]];
    if (listing.message_count == 0 || message.log_time_ns < listing.first_log_time_ns) {
      listing.first_log_time_ns = message.log_time_ns;
    }
    if (listing.message_count == 0 || message.log_time_ns > listing.last_log_time_ns) {
      listing.last_log_time_ns = message.log_time_ns;
    }
    ++listing.message_count;
  }
  if (warnings != nullptr) *warnings = ReadWarnings(*reader);
  std::vector<TopicListing> list;
  for (auto& entry : topics) list.push_back(std::move(entry.second));
  return list;
}

std::string FormatTopicList(const std::vector<TopicListing>& topics) {
  size_t topic_width = 5, type_width = 4;
  for (const TopicListing& t : topics) {
    topic_width = std::max(topic_width, t.topic.size());
    type_width = std::max(type_width, t.type.size());
  }
  const auto pad = [](std::string text, size_t width) {
    text.resize(std::max(text.size(), width), ' ');
    return text;
  };
  std::string out = pad("topic", topic_width) + "  " + pad("type", type_width) +
                    "  messages    span_s   rate_hz\n";
  for (const TopicListing& t : topics) {
    char numbers[96];
    std::snprintf(numbers, sizeof(numbers), "%10llu %9.3f %9.3f",
                  static_cast<unsigned long long>(t.message_count), t.span_s(), t.mean_rate_hz());
    out += pad(t.topic, topic_width) + "  " + pad(t.type, type_width) + numbers + "\n";
  }
  return out;
}

std::string ImportSummary::FormatText() const {
  std::string out = "dataset: " + output + "\n";
  const auto line = [&](const char* what, const ImportedStream& s) {
    if (s.topic.empty()) {
      out += std::string("  ") + what + ": not imported (no topic)\n";
      return;
    }
    out += std::string("  ") + what + ": " + s.topic + " (" + s.type +
           "): " + std::to_string(s.messages) + " messages, " + std::to_string(s.written) +
           " written\n";
  };
  line("imu.csv     ", imu);
  line("lidar/      ", lidar);
  line("wheel.csv   ", wheel);
  line("gnss.csv    ", gnss);
  line("odometry.csv", odometry);
  out += "  static transforms: " + std::to_string(static_transforms) + " messages\n";
  for (const std::string& warning : warnings) out += "warning: " + warning + "\n";
  return out;
}

}  // namespace import
}  // namespace autocal
