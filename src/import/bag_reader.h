#pragma once

// One interface over the three recorded-log containers autocal imports: ROS 1 bags
// (format 2.0), MCAP files and rosbag2 SQLite files (or a rosbag2 directory holding either).
// A reader yields the file's connections (topic, type, serialization) and then its messages
// as raw serialized bytes; decoding the messages is the job of ros_messages.h.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "autocal/common/error.h"

namespace autocal {
namespace import {

// How a message's bytes are laid out: ROS 1 serialization (packed little-endian, no
// alignment) or CDR as ROS 2 writes it (4-byte encapsulation header, aligned primitives).
enum class Serialization { kRos1, kCdr };

struct Connection {
  uint32_t id = 0;    // unique within one reader
  std::string topic;  // "/imu/data"
  std::string type;   // as stored: "sensor_msgs/Imu" (ROS 1) or "sensor_msgs/msg/Imu" (ROS 2)
  Serialization serialization = Serialization::kRos1;
};

struct BagMessage {
  uint32_t connection_id = 0;
  int64_t log_time_ns = 0;   // when the recorder received it (bag record time)
  std::string_view data;     // the serialized message; valid until the next call of Next()
  uint64_t file_offset = 0;  // byte offset of the record holding it (0 in SQLite files)
  int64_t row_id = -1;       // SQLite files: the message's row, which stands in for an offset
};

// What the container's own index or summary says of one connection, when it has one.
struct IndexedTopic {
  uint32_t connection_id = 0;
  uint64_t message_count = 0;
  int64_t first_log_time_ns = 0;
  int64_t last_log_time_ns = 0;
};

class BagReader {
 public:
  virtual ~BagReader() = default;

  virtual const std::string& path() const = 0;
  virtual const std::vector<Connection>& connections() const = 0;
  // The container's index / summary per connection, or nullopt when the file has none (an
  // unindexed ROS 1 bag, an MCAP file without summary).
  virtual std::optional<std::vector<IndexedTopic>> IndexedTopics() const = 0;
  // The next message in file order; false at the end. Throws autocal::ParseError (path, byte
  // offset and record kind) on a malformed file.
  virtual bool Next(BagMessage* message) = 0;
  // What the reader recovered or left so far, one sentence each naming the file and byte
  // (a ROS 1 bag whose recorder stopped mid-write: the records its last chunk holds whole).
  virtual std::vector<std::string> Warnings() const { return {}; }
};

// The warnings a full read of `reader` leaves for its user: a missing index (read by a linear
// scan), then the reader's Warnings().
std::vector<std::string> ReadWarnings(const BagReader& reader);

// Where a message sits in its file, for error messages: "<path>: byte N", or for a row of a
// SQLite file "<path> (row N)".
SourceLocation MessageLocation(const std::string& path, const BagMessage& message);

// Opens `path` by what it is: a rosbag2 directory (with its metadata.yaml, or without it, as a
// part of a split recording comes), a `.bag` file (ROS 1), a `.mcap` file or a `.db3` file;
// the magic bytes decide when the extension is unknown.
std::unique_ptr<BagReader> OpenBag(const std::string& path);

// The containers OpenBag dispatches to.
std::unique_ptr<BagReader> OpenRos1Bag(const std::string& path);          // ros1_bag.cc
std::unique_ptr<BagReader> OpenMcap(const std::string& path);             // mcap_reader.cc
std::unique_ptr<BagReader> OpenRosbag2Sqlite(const std::string& path);    // rosbag2_sqlite.cc
std::unique_ptr<BagReader> OpenRosbag2Directory(const std::string& dir);  // rosbag2_directory.cc

}  // namespace import
}  // namespace autocal
