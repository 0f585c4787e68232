#include "import/rosbag2_metadata.h"

#include <cstdint>
#include <limits>
#include <string>

#include "io/yaml_util.h"

namespace autocal {
namespace import {
namespace internal {

namespace {

using io::internal::YamlFile;

// An optional string key ("" when absent).
std::string OptionalString(const YamlFile& file, const YAML::Node& map, const char* key,
                           const std::string& what) {
  const YAML::Node node = map[key];
  if (!node.IsDefined() || node.IsNull()) return "";
  return file.String(node, what + "." + key);
}

// The child `key` of `map`, which must be a map: a ParseError at its line:column when the
// node is a scalar or a list (yaml-cpp's own operator[] would throw an exception of its own).
YAML::Node Required(const YamlFile& file, const YAML::Node& map, const std::string& what,
                    const char* key) {
  if (!map.IsMap()) file.Fail(map, what + ": expected a map");
  return file.Required(map, what, key);
}

Rosbag2Topic ReadTopic(const YamlFile& file, const YAML::Node& entry, const std::string& what) {
  const YAML::Node metadata = Required(file, entry, what, "topic_metadata");
  Rosbag2Topic topic;
  topic.name = file.String(Required(file, metadata, what, "name"), what + ".name");
  topic.type = file.String(Required(file, metadata, what, "type"), what + ".type");
  topic.serialization_format = file.String(Required(file, metadata, what, "serialization_format"),
                                           what + ".serialization_format");
  const int64_t count =
      file.Int(Required(file, entry, what, "message_count"), what + ".message_count");
  if (count < 0) file.Fail(entry["message_count"], what + ".message_count: negative");
  topic.message_count = static_cast<uint64_t>(count);
  return topic;
}

}  // namespace

Rosbag2Metadata ReadRosbag2Metadata(const std::string& path) {
  const YamlFile file(path);
  const std::string what = "rosbag2_bagfile_information";
  const YAML::Node info = Required(file, file.root(), "metadata.yaml", what.c_str());
  Rosbag2Metadata metadata;
  metadata.storage_identifier =
      file.String(Required(file, info, what, "storage_identifier"), what + ".storage_identifier");

  const YAML::Node files = Required(file, info, what, "relative_file_paths");
  if (!files.IsSequence()) file.Fail(files, what + ".relative_file_paths: expected a list");
  for (size_t i = 0; i < files.size(); ++i) {
    metadata.relative_files.push_back(
        file.String(files[i], what + ".relative_file_paths[" + std::to_string(i) + "]"));
  }

  const YAML::Node topics = Required(file, info, what, "topics_with_message_count");
  if (!topics.IsSequence() && !topics.IsNull()) {
    file.Fail(topics, what + ".topics_with_message_count: expected a list");
  }
  for (size_t i = 0; i < topics.size(); ++i) {
    metadata.topics.push_back(
        ReadTopic(file, topics[i], what + ".topics_with_message_count[" + std::to_string(i) + "]"));
  }

  const YAML::Node start = Required(file, info, what, "starting_time");
  metadata.starting_time_ns =
      file.Int(Required(file, start, what + ".starting_time", "nanoseconds_since_epoch"),
               what + ".starting_time.nanoseconds_since_epoch");
  const YAML::Node duration = Required(file, info, what, "duration");
  const YAML::Node duration_ns = Required(file, duration, what + ".duration", "nanoseconds");
  metadata.duration_ns = file.Int(duration_ns, what + ".duration.nanoseconds");
  // The recording's end, starting_time + duration, must be a time too.
  if (metadata.duration_ns < 0 ||
      metadata.starting_time_ns > std::numeric_limits<int64_t>::max() - metadata.duration_ns) {
    file.Fail(duration_ns, what +
                               ".duration.nanoseconds: expected a duration of 0 or more that "
                               "ends before the year 2262, got " +
                               std::to_string(metadata.duration_ns));
  }
  metadata.compression_mode = OptionalString(file, info, "compression_mode", what);
  metadata.compression_format = OptionalString(file, info, "compression_format", what);
  return metadata;
}

}  // namespace internal
}  // namespace import
}  // namespace autocal
