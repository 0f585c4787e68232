#include "import/mcap_summary.h"

#include <algorithm>
#include <cstring>

namespace autocal {
namespace import {
namespace internal {

void McapChannels::AddSchema(McapFields* fields) {
  const uint16_t id = fields->U16("id");
  const std::string name(fields->Prefixed32("name"));
  fields->Prefixed32("encoding");
  fields->Prefixed32("data");
  if (id == 0) return;  // invalid by the spec, and to be ignored
  const auto [it, inserted] = schema_names_.emplace(id, name);
  if (!inserted && it->second != name) {
    fields->Fail("schema " + std::to_string(id) + " was '" + it->second + "', now '" + name + "'");
  }
}

uint16_t McapChannels::AddChannel(McapFields* fields, bool must_be_known) {
  Connection connection;
  const uint16_t id = fields->U16("id");
  const uint16_t schema_id = fields->U16("schema_id");
  connection.id = id;
  connection.topic = std::string(fields->Prefixed32("topic"));
  const std::string_view encoding = fields->Prefixed32("message_encoding");
  fields->Prefixed32("metadata");
  if (schema_id != 0) {
    const auto schema = schema_names_.find(schema_id);
    if (schema == schema_names_.end()) {
      fields->Fail("channel '" + connection.topic + "' refers to schema " +
                   std::to_string(schema_id) + ", which no Schema record before it defines");
    }
    connection.type = schema->second;
  }
  if (encoding == "cdr") {
    connection.serialization = Serialization::kCdr;
  } else if (encoding == "ros1") {
    connection.serialization = Serialization::kRos1;
  } else {
    fields->Fail("channel '" + connection.topic + "' has message encoding '" +
                 std::string(encoding) + "': only cdr (ROS 2) and ros1 messages are read");
  }
  const auto known = channels_.find(id);
  if (known == channels_.end()) {
    if (must_be_known) {
      fields->Fail("channel " + std::to_string(id) + " ('" + connection.topic +
                   "') is missing from the summary section, which must list every channel");
    }
    channels_.emplace(id, connection);
  } else if (known->second.topic != connection.topic || known->second.type != connection.type ||
             known->second.serialization != connection.serialization) {
    fields->Fail("channel " + std::to_string(id) + " was '" + known->second.topic + "' (" +
                 known->second.type + "), now '" + connection.topic + "' (" + connection.type +
                 ")");
  }
  return id;
}

std::vector<Connection> McapChannels::Connections() const {
  std::vector<Connection> connections;
  for (const auto& [id, connection] : channels_) connections.push_back(connection);
  return connections;
}

McapSummary::McapSummary(const std::string& path, std::string_view file, uint64_t start,
                         uint64_t end)
    : path_(path), file_(file), place_{&path_} {
  if (start == 0) return;
  uint64_t pos = start;
  while (pos < end) {
    uint64_t length = 0;
    if (end - pos >= kMcapRecordPrefixBytes) std::memcpy(&length, file_.data() + pos + 1, 8);
    const uint8_t opcode = static_cast<uint8_t>(file_[pos]);
    if (end - pos < kMcapRecordPrefixBytes || length > end - pos - kMcapRecordPrefixBytes) {
      place_.Fail(pos, opcode, "it runs past the end of the summary section");
    }
    McapFields fields(file_.substr(pos + kMcapRecordPrefixBytes, length),
                      pos + kMcapRecordPrefixBytes, opcode, place_);
    switch (opcode) {
      case kOpSchema:
        channels_.AddSchema(&fields);
        break;
      case kOpChannel:
        channels_.AddChannel(&fields, /*must_be_known=*/false);
        break;
      case kOpStatistics:
        ReadStatistics(&fields);
        break;
      case kOpChunkIndex:
        ReadChunkIndex(&fields);
        break;
      default:
        break;  // attachment and metadata indexes, unknown records
    }
    pos += kMcapRecordPrefixBytes + length;
  }
}

void McapSummary::ReadStatistics(McapFields* fields) {
  Statistics statistics;
  statistics.message_count = fields->U64("message_count");
  fields->U16("schema_count");
  fields->U32("channel_count");
  fields->U32("attachment_count");
  fields->U32("metadata_count");
  fields->U32("chunk_count");
  statistics.message_start_time_ns = fields->Time("message_start_time");
  statistics.message_end_time_ns = fields->Time("message_end_time");
  const std::string_view counts = fields->Prefixed32("channel_message_counts");
  McapFields map(counts, fields->offset() - counts.size(), kOpStatistics, place_);
  while (map.remaining() > 0) {
    const uint16_t channel_id = map.U16("channel_message_counts key");
    statistics.channel_message_counts[channel_id] = map.U64("channel_message_counts value");
  }
  statistics_ = statistics;
}

void McapSummary::ReadChunkIndex(McapFields* fields) {
  fields->Time("message_start_time");
  fields->Time("message_end_time");
  fields->U64("chunk_start_offset");
  fields->U64("chunk_length");
  const std::string_view offsets = fields->Prefixed32("message_index_offsets");
  McapFields map(offsets, fields->offset() - offsets.size(), kOpChunkIndex, place_);
  while (map.remaining() > 0) {
    const uint16_t channel_id = map.U16("message_index_offsets key");
    ReadMessageIndex(channel_id, map.U64("message_index_offsets value"));
  }
}

// One channel's (log_time, offset) pairs for one chunk.
void McapSummary::ReadMessageIndex(uint16_t channel_id, uint64_t offset) {
  uint64_t length = 0;
  const bool fits = offset < file_.size() && file_.size() - offset >= kMcapRecordPrefixBytes;
  if (fits) std::memcpy(&length, file_.data() + offset + 1, 8);
  if (!fits || static_cast<uint8_t>(file_[offset]) != kOpMessageIndex ||
      length > file_.size() - offset - kMcapRecordPrefixBytes) {
    place_.Fail(offset, kOpMessageIndex,
                "expected here by a Chunk Index (channel " + std::to_string(channel_id) + ")");
  }
  // Each indexes one channel of one chunk: a second reference would count its messages again
  // (and many would read one large record over and over).
  if (!message_indexes_read_.insert(offset).second) {
    place_.Fail(offset, kOpMessageIndex,
                "referenced a second time by the Chunk Indexes (channel " +
                    std::to_string(channel_id) + ")");
  }
  McapFields fields(file_.substr(offset + kMcapRecordPrefixBytes, length),
                    offset + kMcapRecordPrefixBytes, kOpMessageIndex, place_);
  if (fields.U16("channel_id") != channel_id) {
    fields.Fail("its channel differs from the Chunk Index's " + std::to_string(channel_id));
  }
  const std::string_view entries = fields.Prefixed32("records");
  McapFields array(entries, fields.offset() - entries.size(), kOpMessageIndex, place_);
  IndexedChannel& indexed = indexed_[channel_id];
  while (array.remaining() > 0) {
    const int64_t log_time_ns = array.Time("records log_time");
    array.U64("records offset");
    indexed.first_ns = indexed.count == 0 ? log_time_ns : std::min(indexed.first_ns, log_time_ns);
    indexed.last_ns = indexed.count == 0 ? log_time_ns : std::max(indexed.last_ns, log_time_ns);
    ++indexed.count;
  }
}

std::optional<std::vector<IndexedTopic>> McapSummary::IndexedTopics(
    const std::vector<Connection>& connections) const {
  // An empty channel_message_counts means "not available", unless the file has no message.
  const bool has_counts = statistics_ && (!statistics_->channel_message_counts.empty() ||
                                          statistics_->message_count == 0);
  if (!has_counts && indexed_.empty()) return std::nullopt;
  std::vector<IndexedTopic> topics;
  for (const Connection& connection : connections) {
    const uint16_t id = static_cast<uint16_t>(connection.id);
    IndexedTopic topic;
    topic.connection_id = connection.id;
    const auto from_index = indexed_.find(id);
    if (has_counts) {
      const auto count = statistics_->channel_message_counts.find(id);
      topic.message_count = count == statistics_->channel_message_counts.end() ? 0 : count->second;
    } else if (from_index != indexed_.end()) {
      topic.message_count = from_index->second.count;
    }
    if (from_index != indexed_.end() && from_index->second.count == topic.message_count) {
      topic.first_log_time_ns = from_index->second.first_ns;
      topic.last_log_time_ns = from_index->second.last_ns;
    } else if (topic.message_count > 0 && statistics_) {
      // Messages outside chunks are not indexed: the file's span bounds the channel's.
      topic.first_log_time_ns = statistics_->message_start_time_ns;
      topic.last_log_time_ns = statistics_->message_end_time_ns;
    }
    topics.push_back(topic);
  }
  return topics;
}

}  // namespace internal
}  // namespace import
}  // namespace autocal
