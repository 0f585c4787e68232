// The ROS 1 bag reader on bags written by test/import/ros1_bag_writer.h: every chunk
// compression, the index against what a full read finds, unindexed bags, and one clear
// error (file, byte offset, record kind) for each kind of bad input.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <random>

#include "autocal/common/error.h"
#include "autocal/import/import_bag.h"
#include "import/bag_reader.h"
#include "import/ros1_bag_writer.h"
#include "support/test_paths.h"

namespace autocal {
namespace import {
namespace {

using test::Ros1BagWriter;
using ::testing::HasSubstr;

constexpr int64_t kStartNs = 1700000000000000000;

// A message whose bytes say which one it is.
std::string Payload(uint32_t connection, int i) {
  return "conn " + std::to_string(connection) + " message " + std::to_string(i) +
         std::string(static_cast<size_t>(i % 50), 'x');
}

// Two topics interleaved, 300 and 150 messages, several chunks.
std::string MakeBag(Ros1BagWriter::Compression compression, bool indexed) {
  Ros1BagWriter::Options options;
  options.compression = compression;
  options.chunk_bytes = 4096;
  options.indexed = indexed;
  Ros1BagWriter writer(options);
  const uint32_t imu = writer.AddConnection("/imu", "sensor_msgs/Imu");
  const uint32_t fix = writer.AddConnection("/fix", "sensor_msgs/NavSatFix");
  for (int i = 0; i < 300; ++i) {
    writer.Write(imu, kStartNs + i * 10000000LL, Payload(imu, i));
    if (i % 2 == 0) writer.Write(fix, kStartNs + i * 10000000LL + 5, Payload(fix, i / 2));
  }
  return writer.Finish();
}

std::string WriteBag(const std::string& name, const std::string& bytes) {
  const std::string path = (test::OutputDir("bags") / name).string();
  Ros1BagWriter::WriteFile(path, bytes);
  return path;
}

struct ReadBack {
  std::map<std::string, std::vector<std::string>> payloads;  // by topic
  std::map<std::string, std::pair<int64_t, int64_t>> span;
};

ReadBack ReadAll(BagReader* reader) {
  std::map<uint32_t, std::string> topic;
  for (const Connection& c : reader->connections()) topic[c.id] = c.topic;
  ReadBack back;
  BagMessage message;
  while (reader->Next(&message)) {
    const std::string& t = topic.at(message.connection_id);
    if (back.payloads[t].empty()) back.span[t].first = message.log_time_ns;
    back.span[t].second = message.log_time_ns;
    back.payloads[t].emplace_back(message.data);
  }
  return back;
}

std::string CompressionName(Ros1BagWriter::Compression compression) {
  switch (compression) {
    case Ros1BagWriter::Compression::kNone:
      return "None";
    case Ros1BagWriter::Compression::kBz2:
      return "Bz2";
    case Ros1BagWriter::Compression::kLz4:
      return "Lz4";
  }
  return "?";
}

class Ros1BagCompressionTest : public ::testing::TestWithParam<Ros1BagWriter::Compression> {};

INSTANTIATE_TEST_SUITE_P(Compressions, Ros1BagCompressionTest,
                         ::testing::Values(Ros1BagWriter::Compression::kNone,
                                           Ros1BagWriter::Compression::kBz2,
                                           Ros1BagWriter::Compression::kLz4),
                         [](const auto& info) { return CompressionName(info.param); });

TEST_P(Ros1BagCompressionTest, ReadsEveryMessageInOrderAndTheIndexAgrees) {
  const std::string path = WriteBag("bag.bag", MakeBag(GetParam(), true));
  const std::unique_ptr<BagReader> reader = OpenBag(path);
  ASSERT_EQ(reader->connections().size(), 2u);
  EXPECT_EQ(reader->connections()[0].topic, "/imu");
  EXPECT_EQ(reader->connections()[0].type, "sensor_msgs/Imu");
  EXPECT_EQ(reader->connections()[0].serialization, Serialization::kRos1);
  const ReadBack back = ReadAll(reader.get());
  ASSERT_EQ(back.payloads.at("/imu").size(), 300u);
  ASSERT_EQ(back.payloads.at("/fix").size(), 150u);
  for (int i = 0; i < 300; ++i) EXPECT_EQ(back.payloads.at("/imu")[i], Payload(0, i));
  for (int i = 0; i < 150; ++i) EXPECT_EQ(back.payloads.at("/fix")[i], Payload(1, i));

  const auto indexed = reader->IndexedTopics();
  ASSERT_TRUE(indexed.has_value());
  ASSERT_EQ(indexed->size(), 2u);
  for (const IndexedTopic& topic : *indexed) {
    const std::string name = topic.connection_id == 0 ? "/imu" : "/fix";
    EXPECT_EQ(topic.message_count, back.payloads.at(name).size()) << name;
    EXPECT_EQ(topic.first_log_time_ns, back.span.at(name).first) << name;
    EXPECT_EQ(topic.last_log_time_ns, back.span.at(name).second) << name;
  }
  EXPECT_EQ((*indexed)[0].last_log_time_ns, kStartNs + 299 * 10000000LL);
}

TEST_P(Ros1BagCompressionTest, UnindexedBagIsReadByALinearScan) {
  const std::string path = WriteBag("unindexed.bag", MakeBag(GetParam(), false));
  const std::unique_ptr<BagReader> reader = OpenBag(path);
  EXPECT_FALSE(reader->IndexedTopics().has_value());
  ASSERT_EQ(reader->connections().size(), 2u);
  const ReadBack back = ReadAll(reader.get());
  EXPECT_EQ(back.payloads.at("/imu").size(), 300u);
  EXPECT_EQ(back.payloads.at("/fix").size(), 150u);
  EXPECT_EQ(back.payloads.at("/fix")[149], Payload(1, 149));
}

TEST(Ros1BagTest, BagWithoutChunkInfosIsReadByALinearScan) {
  Ros1BagWriter::Options options;
  options.compression = Ros1BagWriter::Compression::kBz2;
  options.chunk_bytes = 512;
  options.chunk_infos = false;
  Ros1BagWriter writer(options);
  const uint32_t a = writer.AddConnection("/a", "std_msgs/String");
  for (int i = 0; i < 40; ++i) writer.Write(a, kStartNs + i, Payload(a, i));
  const std::string path = WriteBag("no_chunk_infos.bag", writer.Finish());
  const std::unique_ptr<BagReader> reader = OpenBag(path);
  EXPECT_FALSE(reader->IndexedTopics().has_value());
  const ReadBack back = ReadAll(reader.get());
  ASSERT_EQ(back.payloads.at("/a").size(), 40u);
  EXPECT_EQ(back.payloads.at("/a")[39], Payload(a, 39));
}

// A recorder that stops without closing its bag (killed, out of power) leaves index_pos 0 and
// its last chunk open, with rosbag's placeholder sizes 0 and 0; the bag is read to the open
// chunk's last whole record, and a warning says where and how much.
TEST_P(Ros1BagCompressionTest, BagOfAStoppedRecorderIsReadToItsLastWholeRecord) {
  Ros1BagWriter::Options options;
  options.compression = GetParam();
  options.chunk_bytes = 1 << 20;
  Ros1BagWriter writer(options);
  const uint32_t imu = writer.AddConnection("/imu", "sensor_msgs/Imu");
  std::vector<std::string> written;
  for (int i = 0; i < 2200; ++i) {
    written.push_back(Payload(imu, i));
    writer.Write(imu, kStartNs + i * 5000000LL, written.back());
    if (i == 99 || i == 199) writer.EndChunk();  // two closed chunks, then the open one
  }
  const size_t open_chunk_at = writer.size();
  const std::string whole = writer.StoppedInChunk(std::string::npos);
  for (const bool cut : {false, true}) {
    // 100 bytes: less than the last record (114 bytes), more than a bz2 stream's end mark.
    SCOPED_TRACE(cut ? "cut 100 bytes before its end" : "whole");
    const std::string path =
        WriteBag("stopped.bag", cut ? whole.substr(0, whole.size() - 100) : whole);
    const std::unique_ptr<BagReader> reader = OpenBag(path);
    EXPECT_FALSE(reader->IndexedTopics().has_value());
    const ReadBack back = ReadAll(reader.get());
    const std::vector<std::string>& read = back.payloads.at("/imu");
    ASSERT_LE(read.size(), written.size());
    EXPECT_TRUE(std::equal(read.begin(), read.end(), written.begin()));
    size_t expected = written.size();
    if (cut) {
      // The last record is cut; a cut bz2 stream gives nothing before its end (one block
      // here), a cut lz4 frame its whole 64 KiB blocks.
      if (GetParam() == Ros1BagWriter::Compression::kNone) expected = written.size() - 1;
      if (GetParam() == Ros1BagWriter::Compression::kBz2) expected = 200;
    }
    if (GetParam() == Ros1BagWriter::Compression::kLz4 && cut) {
      EXPECT_GT(read.size(), 1000u);
      EXPECT_LT(read.size(), written.size());
    } else {
      EXPECT_EQ(read.size(), expected);
    }
    const std::vector<std::string> warnings = reader->Warnings();
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_THAT(warnings[0], HasSubstr("stopped.bag: byte " + std::to_string(open_chunk_at) +
                                       ": the last chunk was left open (the recorder stopped"));
    EXPECT_THAT(warnings[0],
                HasSubstr(": " + std::to_string(read.size() - 200) + " messages read from it"));
    if (cut && GetParam() != Ros1BagWriter::Compression::kNone) {
      EXPECT_THAT(warnings[0], HasSubstr("stream is cut short"));
    }
    // What the import and --list tell their user: no index, then the open chunk.
    std::vector<std::string> listed;
    ListTopics(path, &listed);
    ASSERT_EQ(listed.size(), 2u);
    EXPECT_THAT(listed[0], HasSubstr("no (complete) index; it was read by a linear scan"));
    EXPECT_EQ(listed[1], warnings[0]);
  }
}

// Cut by the file's end elsewhere: inside a chunk that has its sizes, inside the index data
// record after it, inside a record's header. Every whole chunk is read.
TEST(Ros1BagTest, BagCutShortWithoutAnIndexIsReadToItsLastWholeRecord) {
  Ros1BagWriter::Options options;
  options.chunk_bytes = 1 << 20;
  Ros1BagWriter writer(options);
  const uint32_t a = writer.AddConnection("/a", "std_msgs/String");
  size_t second_chunk_at = 0;
  for (int i = 0; i < 40; ++i) {
    writer.Write(a, kStartNs + i, Payload(a, i));
    if (i == 19) {
      writer.EndChunk();
      second_chunk_at = writer.size();
    }
  }
  const std::string bytes = writer.Unfinished();
  // The index data record after the second chunk: header fields op (4 + 4 bytes), ver, conn
  // and count (4 + 8 each), 20 entries of 12 bytes.
  const size_t index_record_bytes = 4 + (8 + 12 + 13 + 14) + 4 + 20 * 12;
  struct Case {
    size_t size;
    size_t messages;
    std::string warning;
  };
  const std::string index_cut = "the last record is cut short by the file's end";
  for (const Case& c : std::vector<Case>{
           {bytes.size() - index_record_bytes - 10, 39,
            "byte " + std::to_string(second_chunk_at) +
                ": the last chunk is cut short by the file's end: 19 messages read from it; a "
                "record cut short"},
           {bytes.size() - 5, 40, index_cut},
           {second_chunk_at + 3, 20, index_cut}}) {
    SCOPED_TRACE(c.size);
    ASSERT_LT(c.size, bytes.size());
    const std::string path = WriteBag("cut.bag", bytes.substr(0, c.size));
    const std::unique_ptr<BagReader> reader = OpenBag(path);
    const ReadBack back = ReadAll(reader.get());
    EXPECT_EQ(back.payloads.at("/a").size(), c.messages);
    ASSERT_EQ(reader->Warnings().size(), 1u);
    EXPECT_THAT(reader->Warnings()[0], HasSubstr(c.warning));
  }
}

// The error of opening and reading `bytes` whole.
std::string ErrorOf(const std::string& name, const std::string& bytes) {
  const std::string path = WriteBag(name, bytes);
  try {
    const std::unique_ptr<BagReader> reader = OpenBag(path);
    BagMessage message;
    while (reader->Next(&message)) {
    }
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

TEST(Ros1BagTest, BadMagicIsRefusedAtByteZero) {
  std::string bytes = MakeBag(Ros1BagWriter::Compression::kNone, true);
  bytes[1] = 'X';
  const std::string error = ErrorOf("magic.bag", bytes);
  EXPECT_THAT(error, HasSubstr("magic.bag: byte 0: bad magic"));
  EXPECT_THAT(ErrorOf("short.bag", "#ROS"), HasSubstr("bad magic"));
}

TEST(Ros1BagTest, TruncatedFilesAreRefusedWithTheOffset) {
  const std::string bytes = MakeBag(Ros1BagWriter::Compression::kBz2, true);
  // Cut inside the index: the bag header points past the end.
  EXPECT_THAT(ErrorOf("cut_index.bag", bytes.substr(0, bytes.size() - 10)),
              HasSubstr("truncated file"));
  // An indexed bag cut inside its chunks: the index says the bag was closed, so its data is
  // damaged, not left by a recorder that stopped (BagCutShortWithoutAnIndex...).
  std::string indexed = MakeBag(Ros1BagWriter::Compression::kNone, true);
  indexed.resize(4096 + 13 + 500);
  EXPECT_THAT(ErrorOf("cut_chunk.bag", indexed),
              HasSubstr("byte 13: truncated file: the bag header puts the index at byte"));
}

// The open file descriptors of this process.
size_t OpenDescriptors() {
  size_t count = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator("/proc/self/fd")) {
    ++count;
  }
  return count;
}

// Regression (fuzz_ros1_bag): a bag refused while it was being opened left its file open, so
// a long-running caller opening many bad bags ran out of file descriptors.
TEST(Ros1BagTest, RefusedBagDoesNotKeepItsFileOpen) {
  std::string bytes = MakeBag(Ros1BagWriter::Compression::kNone, true);
  const std::string path = WriteBag("refused.bag", bytes.substr(0, bytes.size() - 10));
  const size_t before = OpenDescriptors();
  for (int i = 0; i < 20; ++i) {
    EXPECT_THROW(OpenRos1Bag(path), ParseError);
  }
  EXPECT_EQ(OpenDescriptors(), before);
}

// A bag with one chunk built by hand: `compression` and `declared_size` as given.
std::string HandChunkBag(const std::string& compression, uint32_t declared_size,
                         const std::string& chunk_data) {
  Ros1BagWriter header_only(Ros1BagWriter::Options{Ros1BagWriter::Compression::kNone, 4096, false});
  std::string bytes = header_only.Finish();  // magic + bag header with index_pos 0
  const std::string header = Ros1BagWriter::Field("op", std::string(1, '\x05')) +
                             Ros1BagWriter::Field("compression", compression) +
                             Ros1BagWriter::Field("size", Ros1BagWriter::U32(declared_size));
  return bytes + Ros1BagWriter::Record(header, chunk_data);
}

// A connection record for /a.
std::string ConnectionRecord() {
  return Ros1BagWriter::Record(
      Ros1BagWriter::Field("op", std::string(1, '\x07')) +
          Ros1BagWriter::Field("conn", Ros1BagWriter::U32(0)) + Ros1BagWriter::Field("topic", "/a"),
      Ros1BagWriter::Field("topic", "/a") + Ros1BagWriter::Field("type", "std_msgs/String"));
}

// A connection record and one message on it whose 'time' field holds `time` (8 bytes).
std::string InnerRecords(const std::string& time = Ros1BagWriter::Time(kStartNs)) {
  const std::string message = Ros1BagWriter::Record(
      Ros1BagWriter::Field("op", std::string(1, '\x02')) +
          Ros1BagWriter::Field("conn", Ros1BagWriter::U32(0)) + Ros1BagWriter::Field("time", time),
      "hello");
  return ConnectionRecord() + message;
}

TEST(Ros1BagTest, HandBuiltChunkIsRead) {
  const std::string inner = InnerRecords();
  const std::string path =
      WriteBag("hand.bag", HandChunkBag("none", static_cast<uint32_t>(inner.size()), inner));
  const std::unique_ptr<BagReader> reader = OpenBag(path);
  BagMessage message;
  ASSERT_TRUE(reader->Next(&message));
  EXPECT_EQ(message.data, "hello");
  EXPECT_EQ(message.log_time_ns, kStartNs);
  EXPECT_FALSE(reader->Next(&message));
}

TEST(Ros1BagTest, UnknownCompressionIsRefused) {
  const std::string inner = InnerRecords();
  const std::string error =
      ErrorOf("zip.bag", HandChunkBag("zip", static_cast<uint32_t>(inner.size()), inner));
  EXPECT_THAT(error, HasSubstr("zip.bag: byte 4109: unknown chunk compression 'zip'"));
}

TEST(Ros1BagTest, ChunkWhoseSizeLiesIsRefused) {
  const std::string inner = InnerRecords();
  const uint32_t size = static_cast<uint32_t>(inner.size());
  EXPECT_THAT(ErrorOf("none.bag", HandChunkBag("none", size + 1, inner)),
              HasSubstr("byte 4109: the uncompressed chunk declares size"));
  for (const std::string compression : {"bz2", "lz4"}) {
    SCOPED_TRACE(compression);
    const std::string packed =
        compression == "bz2" ? Ros1BagWriter::Bz2(inner) : Ros1BagWriter::Lz4(inner);
    EXPECT_THAT(ErrorOf("small.bag", HandChunkBag(compression, size - 3, packed)),
                HasSubstr("byte 4109: chunk record: " + compression +
                          " data decompresses to more than the chunk's declared size"));
    EXPECT_THAT(ErrorOf("large.bag", HandChunkBag(compression, size + 3, packed)),
                HasSubstr("bytes but the chunk declares"));
    // Compressed bytes far beyond the declared size: refused before they are read.
    const std::string padded = packed + std::string(70000, '\0');
    EXPECT_THAT(ErrorOf("padded.bag", HandChunkBag(compression, size, padded)),
                HasSubstr("byte 4109: chunk record: the " + compression + " chunk's " +
                          std::to_string(padded.size()) + " compressed bytes are far more than"));
    std::string corrupt = packed;
    corrupt[corrupt.size() / 2] ^= 0x55;
    corrupt[corrupt.size() / 2 + 1] ^= 0x55;
    EXPECT_THAT(ErrorOf("corrupt.bag", HandChunkBag(compression, size, corrupt)),
                HasSubstr("byte 4109: chunk record: " + compression));
  }
}

// Bytes after a chunk's compressed stream: its length is not its stream's, and the records
// after it would be looked for in the wrong place (a length grown over the next chunks dropped
// them without a word).
TEST(Ros1BagTest, ChunkLongerThanItsStreamIsRefused) {
  const std::string inner = InnerRecords();
  const uint32_t size = static_cast<uint32_t>(inner.size());
  for (const std::string compression : {"bz2", "lz4"}) {
    SCOPED_TRACE(compression);
    const std::string packed =
        compression == "bz2" ? Ros1BagWriter::Bz2(inner) : Ros1BagWriter::Lz4(inner);
    EXPECT_THAT(ErrorOf("trailing.bag", HandChunkBag(compression, size, packed + "next record")),
                HasSubstr("byte 4109: chunk record: the " + compression +
                          (compression == "bz2" ? " stream" : " frame") +
                          " ends 11 bytes before the chunk's data does"));
  }
}

// A record time is u32 seconds and u32 nanoseconds: nanoseconds of a second or more are no
// time (taken as they were, the stamp moved by up to 4.3 s).
TEST(Ros1BagTest, RecordTimeWithASecondOfNanosecondsIsRefused) {
  const std::string inner =
      InnerRecords(Ros1BagWriter::U32(1700000000) + Ros1BagWriter::U32(1000000000));
  EXPECT_THAT(ErrorOf("time.bag", HandChunkBag("none", static_cast<uint32_t>(inner.size()), inner)),
              HasSubstr("byte 4109: chunk record: the record at byte " +
                        std::to_string(ConnectionRecord().size()) + " of the uncompressed chunk (" +
                        std::to_string(inner.size()) +
                        " bytes): message data record: 'time' has nanoseconds of 1e9 or more"));
}

TEST(Ros1BagTest, RecordRunningPastItsChunkIsRefused) {
  std::string inner = InnerRecords();
  inner.resize(inner.size() - 2);  // the message data is cut
  const std::string error =
      ErrorOf("inner.bag", HandChunkBag("none", static_cast<uint32_t>(inner.size()), inner));
  EXPECT_THAT(error, HasSubstr("byte 4109: chunk record: the record at byte"));
  EXPECT_THAT(error, HasSubstr("runs past the chunk's end"));
}

// Flipped bytes anywhere in a bag: the reader either reads it or throws autocal::Error,
// never crashes or hangs (the payloads are opaque here, so many flips go unnoticed).
TEST(Ros1BagTest, CorruptedBytesGiveAnErrorOrTheMessages) {
  for (const auto compression :
       {Ros1BagWriter::Compression::kNone, Ros1BagWriter::Compression::kLz4}) {
    const std::string bag = MakeBag(compression, true);
    std::mt19937 random(7);
    std::uniform_int_distribution<size_t> position(0, bag.size() - 1);
    int errors = 0;
    for (int trial = 0; trial < 150; ++trial) {
      std::string bytes = bag;
      for (int flip = 0; flip < 3; ++flip)
        bytes[position(random)] ^= static_cast<char>(1 + trial % 255);
      const std::string error = ErrorOf("fuzz.bag", bytes);
      if (error != "no error") ++errors;
    }
    EXPECT_GT(errors, 0) << CompressionName(compression);
  }
}

TEST(Ros1BagTest, OpenBagDispatchesByMagicAndRefusesOtherFiles) {
  const std::string bag = MakeBag(Ros1BagWriter::Compression::kLz4, true);
  const std::string path = WriteBag("no_extension", bag);
  EXPECT_EQ(OpenBag(path)->connections().size(), 2u);
  const std::string text = WriteBag("text.dat", "hello world, not a bag");
  EXPECT_THROW(OpenBag(text), Error);
  EXPECT_THROW(OpenBag(path + ".missing"), Error);
}

}  // namespace
}  // namespace import
}  // namespace autocal
