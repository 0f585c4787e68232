#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "import/bag_reader.h"
#include "import/crc32.h"
#include "import/mcap_writer.h"
#include "support/test_paths.h"

namespace autocal {
namespace import {
namespace {

using test::CdrString;
using test::McapWriter;
using test::McapWriterOptions;

struct ReadMessage {
  uint32_t connection_id;
  int64_t log_time_ns;
  std::string data;
};

std::vector<ReadMessage> ReadAll(BagReader* reader) {
  std::vector<ReadMessage> messages;
  BagMessage message;
  while (reader->Next(&message)) {
    messages.push_back({message.connection_id, message.log_time_ns, std::string(message.data)});
  }
  return messages;
}

std::string WriteTo(const std::string& name, const std::string& bytes) {
  const std::string path = (test::OutputDir("mcap") / name).string();
  test::WriteFile(path, bytes);
  return path;
}

// Two topics on three channels (two publishers on /imu), messages interleaved.
std::string TwoTopicFile(McapWriterOptions options, int count = 40) {
  McapWriter writer(std::move(options));
  const uint16_t imu_schema = writer.AddSchema("sensor_msgs/msg/Imu");
  const uint16_t string_schema = writer.AddSchema("std_msgs/msg/String");
  const uint16_t imu_a = writer.AddChannel(imu_schema, "/imu");
  const uint16_t chatter = writer.AddChannel(string_schema, "/chatter");
  const uint16_t imu_b = writer.AddChannel(imu_schema, "/imu");
  for (int i = 0; i < count; ++i) {
    const uint16_t channel = i % 3 == 0 ? imu_a : (i % 3 == 1 ? chatter : imu_b);
    writer.AddMessage(channel, 1000 + 10 * i, CdrString("message " + std::to_string(i)));
  }
  return writer.Finish();
}

void ExpectTwoTopicMessages(const std::vector<ReadMessage>& messages, int count = 40) {
  ASSERT_EQ(messages.size(), static_cast<size_t>(count));
  for (int i = 0; i < count; ++i) {
    EXPECT_EQ(messages[i].connection_id, static_cast<uint32_t>(i % 3 + 1)) << "message " << i;
    EXPECT_EQ(messages[i].log_time_ns, 1000 + 10 * i) << "message " << i;
    EXPECT_EQ(messages[i].data, CdrString("message " + std::to_string(i))) << "message " << i;
  }
}

TEST(Crc32, MatchesTheStandardCheckValueAndContinues) {
  EXPECT_EQ(Crc32("123456789"), 0xCBF43926u);
  EXPECT_EQ(Crc32(""), 0u);
  const std::string text = "The quick brown fox jumps over the lazy dog";
  EXPECT_EQ(Crc32(text), 0x414FA339u);
  for (size_t split = 0; split <= text.size(); ++split) {
    EXPECT_EQ(Crc32Update(Crc32(text.substr(0, split)), text.data() + split, text.size() - split),
              Crc32(text))
        << "split at " << split;
  }
}

struct Layout {
  const char* name;
  bool chunked;
  const char* compression;
  bool summary;
};

class McapLayoutTest : public ::testing::TestWithParam<Layout> {};

TEST_P(McapLayoutTest, ReadsEveryMessageInFileOrder) {
  McapWriterOptions options;
  options.chunked = GetParam().chunked;
  options.compression = GetParam().compression;
  options.summary = GetParam().summary;
  options.chunk_bytes = 200;  // several chunks
  const auto reader = OpenMcap(WriteTo("file.mcap", TwoTopicFile(options)));

  const std::vector<Connection>& connections = reader->connections();
  ASSERT_EQ(connections.size(), 3u);
  EXPECT_EQ(connections[0].id, 1u);
  EXPECT_EQ(connections[0].topic, "/imu");
  EXPECT_EQ(connections[0].type, "sensor_msgs/msg/Imu");
  EXPECT_EQ(connections[0].serialization, Serialization::kCdr);
  EXPECT_EQ(connections[1].topic, "/chatter");
  EXPECT_EQ(connections[1].type, "std_msgs/msg/String");
  EXPECT_EQ(connections[2].topic, "/imu");
  ExpectTwoTopicMessages(ReadAll(reader.get()));

  const auto indexed = reader->IndexedTopics();
  ASSERT_EQ(indexed.has_value(), GetParam().summary);
  if (!indexed) return;
  ASSERT_EQ(indexed->size(), 3u);
  // Channel k (1-based) holds messages i = k-1, k+2, ... of 40, stamped 1000 + 10 i.
  const uint64_t counts[] = {14, 13, 13};
  for (int k = 0; k < 3; ++k) {
    const IndexedTopic& topic = (*indexed)[k];
    EXPECT_EQ(topic.connection_id, static_cast<uint32_t>(k + 1));
    EXPECT_EQ(topic.message_count, counts[k]) << "channel " << k + 1;
    if (GetParam().chunked) {  // exact, from the message indexes
      EXPECT_EQ(topic.first_log_time_ns, 1000 + 10 * k);
      EXPECT_EQ(topic.last_log_time_ns, 1000 + 10 * (k + 3 * (counts[k] - 1)));
    } else {  // unindexed messages: the file's span
      EXPECT_EQ(topic.first_log_time_ns, 1000);
      EXPECT_EQ(topic.last_log_time_ns, 1390);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Layouts, McapLayoutTest,
                         ::testing::Values(Layout{"Unchunked", false, "", true},
                                           Layout{"UnchunkedNoSummary", false, "", false},
                                           Layout{"Uncompressed", true, "", true},
                                           Layout{"UncompressedNoSummary", true, "", false},
                                           Layout{"Lz4", true, "lz4", true},
                                           Layout{"Lz4NoSummary", true, "lz4", false},
                                           Layout{"Zstd", true, "zstd", true},
                                           Layout{"ZstdNoSummary", true, "zstd", false}),
                         [](const ::testing::TestParamInfo<Layout>& info) {
                           return info.param.name;
                         });

TEST(McapReader, CountsFromMessageIndexesWithoutStatistics) {
  McapWriterOptions options;
  options.statistics = false;
  options.compression = "zstd";
  const auto reader = OpenMcap(WriteTo("file.mcap", TwoTopicFile(options)));
  const auto indexed = reader->IndexedTopics();
  ASSERT_TRUE(indexed.has_value());
  EXPECT_EQ((*indexed)[0].message_count, 14u);
  EXPECT_EQ((*indexed)[2].last_log_time_ns, 1380);
}

TEST(McapReader, SkipsAttachmentsMetadataAndChecksTheDataSectionCrc) {
  McapWriterOptions options;
  options.data_crc = true;
  options.summary_offsets = false;
  McapWriter writer(options);
  const uint16_t channel = writer.AddChannel(writer.AddSchema("std_msgs/msg/String"), "/a");
  writer.AddMessage(channel, 5, CdrString("first"));
  writer.AddAttachmentAndMetadata();
  writer.AddMessage(channel, 6, CdrString("second"));
  std::string bytes = writer.Finish();
  const std::vector<ReadMessage> messages = ReadAll(OpenMcap(WriteTo("ok.mcap", bytes)).get());
  ASSERT_EQ(messages.size(), 2u);
  EXPECT_EQ(messages[1].data, CdrString("second"));

  // The attachment's name lies outside chunks: only the data section CRC covers it.
  bytes[bytes.find("calibration.yaml")] = 'C';
  const auto reader = OpenMcap(WriteTo("corrupt.mcap", bytes));
  try {
    ReadAll(reader.get());
    FAIL() << "a corrupt data section was read";
  } catch (const ParseError& error) {
    EXPECT_NE(std::string(error.what()).find("Data End record: the CRC-32 of the data section"),
              std::string::npos)
        << error.what();
  }
}

TEST(McapReader, ReadsRos1MessagesAndAFileWithoutAnyMessage) {
  McapWriter writer;
  writer.AddChannel(writer.AddSchema("sensor_msgs/Imu", "ros1msg"), "/imu", "ros1");
  const auto reader = OpenMcap(WriteTo("ros1.mcap", writer.Finish()));
  ASSERT_EQ(reader->connections().size(), 1u);
  EXPECT_EQ(reader->connections()[0].serialization, Serialization::kRos1);
  EXPECT_TRUE(ReadAll(reader.get()).empty());
  ASSERT_TRUE(reader->IndexedTopics().has_value());
  EXPECT_EQ((*reader->IndexedTopics())[0].message_count, 0u);
}

// --- Bad input: one ParseError with the path, the byte offset and the record kind. ---

// Opens and reads `bytes`; returns the ParseError's message ("" when it reads cleanly).
std::string ErrorOf(const std::string& bytes, const std::string& name = "bad.mcap") {
  const std::string path = WriteTo(name, bytes);
  try {
    ReadAll(OpenMcap(path).get());
  } catch (const ParseError& error) {
    EXPECT_EQ(error.location().file, path);
    EXPECT_GE(error.location().byte_offset, 0) << error.what();
    return error.what();
  }
  return "";
}

// A file in memory (memfd) for the tests that read thousands of variants of one file:
// rewriting a file on disk that often costs seconds.
class MemoryFile {
 public:
  MemoryFile() : fd_(memfd_create("mcap_variant", MFD_CLOEXEC)) { EXPECT_GE(fd_, 0); }
  ~MemoryFile() { close(fd_); }
  // Replaces the content; returns a path that opens it.
  std::string Hold(const std::string& bytes) {
    EXPECT_EQ(ftruncate(fd_, 0), 0);
    EXPECT_EQ(pwrite(fd_, bytes.data(), bytes.size(), 0), static_cast<ssize_t>(bytes.size()));
    return "/proc/self/fd/" + std::to_string(fd_);
  }

 private:
  int fd_;
};

std::string ErrorOfFile(const std::string& path) {
  try {
    ReadAll(OpenMcap(path).get());
  } catch (const ParseError& error) {
    EXPECT_EQ(error.location().file, path);
    EXPECT_GE(error.location().byte_offset, 0) << error.what();
    return error.what();
  }
  return "";
}

#define EXPECT_PARSE_ERROR(bytes, fragment)                                             \
  do {                                                                                  \
    const std::string message = ErrorOf(bytes);                                         \
    EXPECT_NE(message.find(fragment), std::string::npos) << "got: '" << message << "'"; \
  } while (0)

template <typename T>
void Poke(std::string* bytes, uint64_t offset, T value) {
  std::memcpy(bytes->data() + offset, &value, sizeof(T));
}

// Chunk content: start, end (8 + 8), uncompressed_size (8), crc (4), compression string.
constexpr uint64_t kChunkUncompressedSize = 9 + 16;
constexpr uint64_t kChunkCrc = 9 + 24;

TEST(McapReaderBadInput, BadMagic) {
  std::string bytes = TwoTopicFile({});
  bytes[1] = 'X';
  EXPECT_PARSE_ERROR(bytes, "bad.mcap: byte 0: not an MCAP file");
  EXPECT_PARSE_ERROR("", "not an MCAP file");
}

TEST(McapReaderBadInput, EveryTruncationIsAParseError) {
  MemoryFile memory;
  for (const char* compression : {"", "zstd"}) {
    for (const bool summary : {true, false}) {
      McapWriterOptions options;
      options.compression = compression;
      options.summary = summary;
      options.chunk_bytes = 64;
      const std::string bytes = TwoTopicFile(options, 6);
      for (size_t size = 0; size < bytes.size(); ++size) {
        const std::string message = ErrorOfFile(memory.Hold(bytes.substr(0, size)));
        EXPECT_FALSE(message.empty()) << "prefix of " << size << " of " << bytes.size()
                                      << " bytes read cleanly (" << compression << ")";
      }
      EXPECT_EQ(ErrorOf(bytes, "whole.mcap"), "");
    }
  }
}

TEST(McapReaderBadInput, EveryFlippedByteIsReadOrRefusedCleanly) {
  McapWriterOptions options;
  options.chunk_bytes = 64;
  options.compression = "lz4";
  const std::string bytes = TwoTopicFile(options, 6);
  int refused = 0;
  MemoryFile memory;
  for (size_t i = 0; i < bytes.size(); ++i) {
    std::string corrupt = bytes;
    corrupt[i] = static_cast<char>(corrupt[i] ^ 0x5A);
    if (!ErrorOfFile(memory.Hold(corrupt)).empty()) ++refused;
  }
  // The CRCs (chunks, summary) and the structure catch 1594 of these 1782 bytes; what is
  // left is what nothing checks: the header's profile and library, a chunk's start and end
  // times, the message indexes' entries (outside every CRC when the data CRC is 0).
  EXPECT_GT(refused, static_cast<int>(bytes.size() * 7 / 8)) << "of " << bytes.size();
}

// The other layouts' paths under the same treatment. zstd chunks without summary (the scan
// at open): 627 of 860 bytes refused, as nothing covers the chunks' times and the message
// indexes. No chunks, with the data section's CRC: 1166 of 1167 refused.
TEST(McapReaderBadInput, EveryFlippedByteOfOtherLayoutsIsReadOrRefused) {
  McapWriterOptions zstd;
  zstd.chunk_bytes = 64;
  zstd.compression = "zstd";
  zstd.summary = false;
  McapWriterOptions unchunked;
  unchunked.chunked = false;
  unchunked.data_crc = true;
  MemoryFile memory;
  for (const auto& [options, least_refused] : {std::pair{zstd, 0.7}, std::pair{unchunked, 0.99}}) {
    const std::string bytes = TwoTopicFile(options, 6);
    int refused = 0;
    for (size_t i = 0; i < bytes.size(); ++i) {
      std::string corrupt = bytes;
      corrupt[i] = static_cast<char>(corrupt[i] ^ 0x5A);
      if (!ErrorOfFile(memory.Hold(corrupt)).empty()) ++refused;
    }
    EXPECT_GT(refused, least_refused * bytes.size()) << "of " << bytes.size();
  }
}

TEST(McapReaderBadInput, UnknownCompression) {
  McapWriterOptions options;
  options.compression = "bz2";
  EXPECT_PARSE_ERROR(TwoTopicFile(options), "Chunk record: unknown compression 'bz2'");
}

TEST(McapReaderBadInput, ChunkLengthPastTheEnd) {
  McapWriter writer;
  writer.AddMessage(writer.AddChannel(writer.AddSchema("t"), "/a"), 1, "x");
  std::string bytes = writer.Finish();
  Poke<uint64_t>(&bytes, writer.chunk_offsets()[0] + 1, 1 << 20);
  const std::string offset = std::to_string(writer.chunk_offsets()[0]);
  EXPECT_PARSE_ERROR(bytes, "byte " + offset + ": Chunk record: its length 1048576 runs past");
}

// The data section must end with its Data End record: a chunk whose length is grown to reach
// the summary would otherwise hide the chunks after it, and the file would read as complete.
TEST(McapReaderBadInput, DataSectionWithoutItsDataEnd) {
  McapWriterOptions options;
  options.data_end = false;
  McapWriter writer(options);
  writer.AddMessage(writer.AddChannel(writer.AddSchema("t"), "/a"), 1, "x");
  EXPECT_PARSE_ERROR(writer.Finish(), "Data End record: missing: the data section ends here");
  McapWriterOptions small_chunks;
  small_chunks.chunk_bytes = 1;  // one chunk per message
  small_chunks.summary_crc = false;
  McapWriter chunks(small_chunks);
  const uint16_t channel = chunks.AddChannel(chunks.AddSchema("t"), "/a");
  for (int i = 0; i < 3; ++i) chunks.AddMessage(channel, 1 + i, "x");
  std::string bytes = chunks.Finish();
  ASSERT_EQ(chunks.chunk_offsets().size(), 3u);
  const uint64_t first = chunks.chunk_offsets()[1];
  const uint64_t data_end = bytes.rfind(std::string("\x0F\x04\0\0\0\0\0\0\0", 9));
  ASSERT_NE(data_end, std::string::npos);
  // The second chunk's length grown over the third and the Data End record.
  Poke<uint64_t>(&bytes, first + 1, data_end + 9 + 4 - first - 9);
  EXPECT_PARSE_ERROR(bytes, "Data End record: missing");
}

// Each Message Index indexes one channel of one chunk: a Chunk Index pointing at another
// chunk's would count its messages twice (and millions of such entries, each reading one large
// record, would hang the opening).
TEST(McapReaderBadInput, MessageIndexReferencedTwice) {
  McapWriterOptions options;
  options.chunk_bytes = 1;  // one chunk per message
  options.summary_crc = false;
  McapWriter writer(options);
  const uint16_t channel = writer.AddChannel(writer.AddSchema("t"), "/a");
  writer.AddMessage(channel, 1, "x");
  writer.AddMessage(channel, 2, "y");
  std::string bytes = writer.Finish();
  ASSERT_EQ(writer.chunk_offsets().size(), 2u);
  const auto message_index_after = [&](uint64_t chunk) {
    uint64_t length;
    std::memcpy(&length, bytes.data() + chunk + 1, 8);
    return chunk + 9 + length;
  };
  const uint64_t first = message_index_after(writer.chunk_offsets()[0]);
  const uint64_t second = message_index_after(writer.chunk_offsets()[1]);
  ASSERT_EQ(static_cast<uint8_t>(bytes[first]), 0x07);
  ASSERT_EQ(static_cast<uint8_t>(bytes[second]), 0x07);
  const size_t reference = bytes.rfind(std::string(reinterpret_cast<const char*>(&second), 8));
  ASSERT_GT(reference, second);  // in the summary's second Chunk Index
  Poke<uint64_t>(&bytes, reference, first);
  EXPECT_PARSE_ERROR(bytes, "byte " + std::to_string(first) +
                                ": Message Index record: referenced a second time by the Chunk "
                                "Indexes (channel " +
                                std::to_string(channel) + ")");
}

TEST(McapReaderBadInput, ChunkUncompressedSizeLies) {
  for (const char* compression : {"", "lz4", "zstd"}) {
    for (const int64_t lie : {-1, 1}) {
      McapWriterOptions options;
      options.compression = compression;
      options.chunk_crc = false;
      McapWriter writer(options);
      writer.AddMessage(writer.AddChannel(writer.AddSchema("t"), "/a"), 1, "payload");
      std::string bytes = writer.Finish();
      const uint64_t field = writer.chunk_offsets()[0] + kChunkUncompressedSize;
      uint64_t size;
      std::memcpy(&size, bytes.data() + field, 8);
      Poke<uint64_t>(&bytes, field, size + lie);
      const std::string message = ErrorOf(bytes);
      EXPECT_NE(message.find("Chunk record: "), std::string::npos) << message;
      EXPECT_NE(message.find(std::to_string(size + lie)), std::string::npos)
          << compression << ": " << message;
    }
  }
}

TEST(McapReaderBadInput, ChunkCrcMismatch) {
  for (const char* compression : {"", "lz4", "zstd"}) {
    McapWriterOptions options;
    options.compression = compression;
    McapWriter writer(options);
    writer.AddMessage(writer.AddChannel(writer.AddSchema("t"), "/a"), 1, "payload");
    std::string bytes = writer.Finish();
    const uint64_t field = writer.chunk_offsets()[0] + kChunkCrc;
    Poke<uint32_t>(&bytes, field, 12345u);
    EXPECT_PARSE_ERROR(bytes, "Chunk record: the CRC-32 of its uncompressed records is");
  }
}

TEST(McapReaderBadInput, SummaryCrcMismatch) {
  std::string bytes = TwoTopicFile({});
  bytes[bytes.rfind("/chatter") + 1] = 'k';
  EXPECT_PARSE_ERROR(bytes, "Footer record: the CRC-32 of the summary section is");
}

TEST(McapReaderBadInput, MessageOnAnUnknownChannel) {
  for (const bool chunked : {true, false}) {
    for (const bool summary : {true, false}) {
      McapWriterOptions options;
      options.chunked = chunked;
      options.summary = summary;
      McapWriter writer(options);
      writer.AddMessage(writer.AddChannel(writer.AddSchema("t"), "/a"), 1, "fine");
      writer.AddMessage(7, 2, "lost");
      const std::string message = ErrorOf(writer.Finish());
      EXPECT_NE(message.find("Message record"), std::string::npos) << message;
      EXPECT_NE(message.find("refers to channel 7, which no Channel record before it defines"),
                std::string::npos)
          << message;
    }
  }
}

TEST(McapReaderBadInput, RefusesJsonWithTheTopic) {
  McapWriter writer;
  writer.AddChannel(writer.AddSchema("Pose", "jsonschema"), "/pose", "json");
  EXPECT_PARSE_ERROR(writer.Finish(), "channel '/pose' has message encoding 'json'");
}

TEST(McapReaderBadInput, ChannelWithAnUnknownSchema) {
  McapWriterOptions options;
  options.summary = false;
  McapWriter writer(options);
  writer.AddChannel(4, "/a");
  EXPECT_PARSE_ERROR(writer.Finish(), "channel '/a' refers to schema 4");
}

// --- The real rosbag2 MCAP files. ---

std::string SharedBag(const std::string& relative) {
  return (test::SharedDataDir("ros2_bags") / relative).string();
}

// The text of a std_msgs/msg/String in CDR: encapsulation, uint32 length with NUL, bytes.
std::string DecodeCdrString(const std::string& data) {
  EXPECT_GE(data.size(), 8u);
  EXPECT_EQ(data.substr(0, 4), std::string("\x00\x01\x00\x00", 4));  // CDR little-endian
  uint32_t length = 0;
  std::memcpy(&length, data.data() + 4, 4);
  EXPECT_GE(length, 1u);
  EXPECT_LE(8 + length, data.size());
  return data.substr(8, length - 1);
}

TEST(McapRealBags, TalkerZstdChunks) {
  const std::string path = SharedBag("talker_mcap/talker.mcap");
  AUTOCAL_REQUIRE_SHARED_DATA(std::filesystem::path(path));
  const auto reader = OpenMcap(path);
  std::map<std::string, uint32_t> ids;
  for (const Connection& connection : reader->connections()) {
    ids[connection.topic] = connection.id;
    EXPECT_EQ(connection.serialization, Serialization::kCdr);
  }
  ASSERT_EQ(ids.size(), 3u);
  const std::vector<ReadMessage> messages = ReadAll(reader.get());
  ASSERT_EQ(messages.size(), 20u);  // metadata.yaml: /topic 10, /rosout 10
  std::vector<std::string> texts;
  for (const ReadMessage& message : messages) {
    if (message.connection_id == ids["/topic"]) texts.push_back(DecodeCdrString(message.data));
  }
  ASSERT_EQ(texts.size(), 10u);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(texts[i], "Hello, world! " + std::to_string(i));
  const auto indexed = reader->IndexedTopics();
  ASSERT_TRUE(indexed.has_value());
  for (const IndexedTopic& topic : *indexed) {
    EXPECT_EQ(topic.message_count, topic.connection_id == ids["/parameter_events"] ? 0u : 10u);
  }
  EXPECT_EQ(messages.front().log_time_ns, 1585866235112411371);  // metadata's starting_time
  EXPECT_EQ(messages.back().log_time_ns - messages.front().log_time_ns, 4531096768);
}

TEST(McapRealBags, CdrTestUncompressed) {
  const std::string path = SharedBag("cdr_test/cdr_test_0.mcap");
  AUTOCAL_REQUIRE_SHARED_DATA(std::filesystem::path(path));
  const auto reader = OpenMcap(path);
  std::map<uint32_t, std::string> types;
  for (const Connection& connection : reader->connections()) types[connection.id] = connection.type;
  std::map<std::string, uint64_t> counts;
  for (const ReadMessage& message : ReadAll(reader.get())) ++counts[types[message.connection_id]];
  EXPECT_EQ(counts["test_msgs/msg/BasicTypes"], 3u);
  EXPECT_EQ(counts["test_msgs/msg/Arrays"], 4u);
}

TEST(McapRealBags, SplitRecordingFirstFileMatchesItsSummary) {
  const std::string path = SharedBag("wbag/wbag_0.mcap");
  AUTOCAL_REQUIRE_SHARED_DATA(std::filesystem::path(path));
  const auto reader = OpenMcap(path);
  EXPECT_EQ(reader->connections().size(), 8u);
  std::map<uint32_t, uint64_t> counts;
  std::map<uint32_t, std::pair<int64_t, int64_t>> span;
  uint64_t total = 0;
  for (const ReadMessage& message : ReadAll(reader.get())) {
    if (counts[message.connection_id]++ == 0)
      span[message.connection_id].first = message.log_time_ns;
    span[message.connection_id].second = message.log_time_ns;
    DecodeCdrString(message.data);
    ++total;
  }
  EXPECT_EQ(total, 1246u);  // the Statistics record's message_count
  const auto indexed = reader->IndexedTopics();
  ASSERT_TRUE(indexed.has_value());
  for (const IndexedTopic& topic : *indexed) {
    EXPECT_EQ(topic.message_count, counts[topic.connection_id]) << topic.connection_id;
    EXPECT_EQ(topic.first_log_time_ns, span[topic.connection_id].first);
    EXPECT_EQ(topic.last_log_time_ns, span[topic.connection_id].second);
  }
}

}  // namespace
}  // namespace import
}  // namespace autocal
