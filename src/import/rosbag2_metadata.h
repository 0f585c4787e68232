#pragma once

// A rosbag2 directory's metadata.yaml (rosbag2_bagfile_information): the
// storage plugin, the files in recording order, the topics with their message counts, the
// bag's start and duration, and the compression.

#include <cstdint>
#include <string>
#include <vector>

namespace autocal {
namespace import {
namespace internal {

struct Rosbag2Topic {
  std::string name;
  std::string type;
  std::string serialization_format;
  uint64_t message_count = 0;
};

struct Rosbag2Metadata {
  std::string storage_identifier;           // "mcap" or "sqlite3"
  std::vector<std::string> relative_files;  // in recording order
  std::vector<Rosbag2Topic> topics;
  int64_t starting_time_ns = 0;
  int64_t duration_ns = 0;
  std::string compression_mode;    // "", "NONE", "FILE" or "MESSAGE"
  std::string compression_format;  // "" or "zstd"
};

// Throws ParseError (file:line:column) on a syntax error or a missing or malformed key.
Rosbag2Metadata ReadRosbag2Metadata(const std::string& path);

}  // namespace internal
}  // namespace import
}  // namespace autocal
