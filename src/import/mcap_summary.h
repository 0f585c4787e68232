#pragma once

// The MCAP file's schemas and channels as connections, and its summary section: the
// Statistics record and the Chunk Index records, with the Message Index records they point
// to, give each channel's message count and first and last log time without decompressing.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "import/bag_reader.h"
#include "import/mcap_format.h"

namespace autocal {
namespace import {
namespace internal {

// The Schema and Channel records met so far, from the summary or the data section.
class McapChannels {
 public:
  // Reads a Schema record's fields; one redefining a known id differently is refused.
  void AddSchema(McapFields* fields);
  // Reads a Channel record's fields and returns its id. Its schema must be known, its
  // message encoding "cdr" or "ros1"; a known id must come back identical; with
  // `must_be_known` an id not met before is refused (the summary lists every channel).
  uint16_t AddChannel(McapFields* fields, bool must_be_known);

  bool HasChannels() const { return !channels_.empty(); }
  // By channel id; Connection::id is the channel id, Connection::type the schema name.
  std::vector<Connection> Connections() const;

 private:
  std::unordered_map<uint16_t, std::string> schema_names_;
  std::map<uint16_t, Connection> channels_;
};

class McapSummary {
 public:
  // Reads the summary section [start, end) of `file` (none when start is 0).
  McapSummary(const std::string& path, std::string_view file, uint64_t start, uint64_t end);

  const McapChannels& channels() const { return channels_; }

  // Per connection: the count from Statistics (else from the message indexes) and the first
  // and last log time from the message indexes (else the file's span from Statistics);
  // nullopt without a summary that says either.
  std::optional<std::vector<IndexedTopic>> IndexedTopics(
      const std::vector<Connection>& connections) const;

 private:
  struct Statistics {
    uint64_t message_count = 0;
    int64_t message_start_time_ns = 0;
    int64_t message_end_time_ns = 0;
    std::unordered_map<uint16_t, uint64_t> channel_message_counts;
  };
  struct IndexedChannel {
    uint64_t count = 0;
    int64_t first_ns = 0;
    int64_t last_ns = 0;
  };

  void ReadStatistics(McapFields* fields);
  void ReadChunkIndex(McapFields* fields);
  void ReadMessageIndex(uint16_t channel_id, uint64_t offset);

  const std::string& path_;
  std::string_view file_;
  McapPlace place_;
  McapChannels channels_;
  std::optional<Statistics> statistics_;
  std::unordered_map<uint16_t, IndexedChannel> indexed_;  // from the message indexes
  std::unordered_set<uint64_t> message_indexes_read_;     // their offsets
};

}  // namespace internal
}  // namespace import
}  // namespace autocal
