#include <gtest/gtest.h>
#include <sqlite3.h>
#include <zstd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "import/bag_reader.h"
#include "import/mcap_writer.h"
#include "support/test_paths.h"

namespace autocal {
namespace import {
namespace {

namespace fs = std::filesystem;
using test::CdrString;
using test::McapWriter;

struct ReadMessage {
  std::string topic;
  int64_t log_time_ns;
  std::string data;
};

std::vector<ReadMessage> ReadAll(BagReader* reader) {
  std::map<uint32_t, std::string> topics;
  for (const Connection& connection : reader->connections()) {
    topics[connection.id] = connection.topic;
  }
  std::vector<ReadMessage> messages;
  BagMessage message;
  while (reader->Next(&message)) {
    EXPECT_EQ(topics.count(message.connection_id), 1u) << message.connection_id;
    messages.push_back(
        {topics[message.connection_id], message.log_time_ns, std::string(message.data)});
  }
  return messages;
}

std::map<std::string, uint64_t> CountByTopic(const std::vector<ReadMessage>& messages) {
  std::map<std::string, uint64_t> counts;
  for (const ReadMessage& message : messages) ++counts[message.topic];
  return counts;
}

// The container's own counts by topic.
std::map<std::string, uint64_t> IndexedCounts(const BagReader& reader) {
  std::map<uint32_t, std::string> topics;
  for (const Connection& connection : reader.connections())
    topics[connection.id] = connection.topic;
  std::map<std::string, uint64_t> counts;
  const auto indexed = reader.IndexedTopics();
  EXPECT_TRUE(indexed.has_value()) << reader.path();
  if (!indexed) return counts;
  for (const IndexedTopic& topic : *indexed) {
    if (topic.message_count > 0) counts[topics[topic.connection_id]] += topic.message_count;
  }
  return counts;
}

// The text of a std_msgs/msg/String in CDR: encapsulation, uint32 length with NUL, bytes.
std::string DecodeCdrString(const std::string& data) {
  if (data.size() < 8 || data.substr(0, 4) != std::string("\x00\x01\x00\x00", 4)) return "?";
  uint32_t length = 0;
  std::memcpy(&length, data.data() + 4, 4);
  if (length < 1 || 8 + length > data.size()) return "?";
  return data.substr(8, length - 1);
}

// --- SQLite (.db3) written here with the rosbag2 schema. ---

class Db3Writer {
 public:
  explicit Db3Writer(const std::string& path) {
    fs::remove(path);
    EXPECT_EQ(sqlite3_open(path.c_str(), &db_), SQLITE_OK);
    Exec("PRAGMA synchronous = OFF");  // a test file: no need to wait for the disk
    Exec("PRAGMA journal_mode = MEMORY");
  }
  ~Db3Writer() { sqlite3_close(db_); }
  void Exec(const std::string& sql) {
    char* error = nullptr;
    EXPECT_EQ(sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error), SQLITE_OK)
        << (error ? error : "") << " in " << sql;
    sqlite3_free(error);
  }
  void CreateTables() {
    Exec(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, "
        "serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL, "
        "type_description_hash TEXT NOT NULL DEFAULT '')");
    Exec(
        "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, "
        "timestamp INTEGER NOT NULL, data BLOB NOT NULL)");
    Exec("CREATE INDEX timestamp_idx ON messages (timestamp ASC)");
  }
  void AddTopic(int id, const std::string& name, const std::string& type,
                const std::string& format = "cdr") {
    Exec("INSERT INTO topics(id, name, type, serialization_format, offered_qos_profiles) VALUES(" +
         std::to_string(id) + ", '" + name + "', '" + type + "', '" + format + "', '')");
  }
  void AddMessage(int topic_id, int64_t time_ns, const std::string& data) {
    sqlite3_stmt* insert = nullptr;
    sqlite3_prepare_v2(db_, "INSERT INTO messages(topic_id, timestamp, data) VALUES(?, ?, ?)", -1,
                       &insert, nullptr);
    sqlite3_bind_int(insert, 1, topic_id);
    sqlite3_bind_int64(insert, 2, time_ns);
    sqlite3_bind_blob(insert, 3, data.data(), static_cast<int>(data.size()), SQLITE_TRANSIENT);
    EXPECT_EQ(sqlite3_step(insert), SQLITE_DONE);
    sqlite3_finalize(insert);
  }

 private:
  sqlite3* db_ = nullptr;
};

std::string OutputFile(const std::string& name) {
  return (test::OutputDir("rosbag2") / name).string();
}

std::string ErrorOf(const std::function<void()>& read) {
  try {
    read();
  } catch (const ParseError& error) {
    return error.what();
  }
  return "";
}

std::string ErrorReadingSqlite(const std::string& path) {
  return ErrorOf([&] { ReadAll(OpenRosbag2Sqlite(path).get()); });
}

std::string ErrorReadingDirectory(const std::string& dir) {
  return ErrorOf([&] { ReadAll(OpenRosbag2Directory(dir).get()); });
}

TEST(Rosbag2Sqlite, ReadsInTimestampOrderWithCounts) {
  const std::string path = OutputFile("bag.db3");
  {
    Db3Writer db(path);
    db.CreateTables();
    db.AddTopic(1, "/chatter", "std_msgs/msg/String");
    db.AddTopic(2, "/imu", "sensor_msgs/msg/Imu");
    db.AddTopic(3, "/silent", "std_msgs/msg/String");
    // Inserted out of time order: the reader must sort by timestamp.
    for (int i = 9; i >= 0; --i)
      db.AddMessage(i % 2 + 1, 100 + 10 * i, CdrString("m" + std::to_string(i)));
  }
  const auto reader = OpenRosbag2Sqlite(path);
  ASSERT_EQ(reader->connections().size(), 3u);
  EXPECT_EQ(reader->connections()[1].topic, "/imu");
  EXPECT_EQ(reader->connections()[1].type, "sensor_msgs/msg/Imu");
  EXPECT_EQ(reader->connections()[1].serialization, Serialization::kCdr);
  const std::vector<ReadMessage> messages = ReadAll(reader.get());
  ASSERT_EQ(messages.size(), 10u);
  for (int i = 0; i < 10; ++i) {
    EXPECT_EQ(messages[i].log_time_ns, 100 + 10 * i);
    EXPECT_EQ(messages[i].topic, i % 2 ? "/imu" : "/chatter");
    EXPECT_EQ(DecodeCdrString(messages[i].data), "m" + std::to_string(i));
  }
  const auto indexed = reader->IndexedTopics();
  ASSERT_TRUE(indexed.has_value());
  ASSERT_EQ(indexed->size(), 3u);
  EXPECT_EQ((*indexed)[0].message_count, 5u);
  EXPECT_EQ((*indexed)[0].first_log_time_ns, 100);
  EXPECT_EQ((*indexed)[0].last_log_time_ns, 180);
  EXPECT_EQ((*indexed)[1].first_log_time_ns, 110);
  EXPECT_EQ((*indexed)[1].last_log_time_ns, 190);
  EXPECT_EQ((*indexed)[2].message_count, 0u);
}

TEST(Rosbag2Sqlite, ReadsThroughALeftoverWriteAheadLog) {
  const std::string path = OutputFile("wal.db3");
  Db3Writer db(path);  // kept open: its messages stay in wal.db3-wal, not in the database
  db.Exec("PRAGMA journal_mode = WAL");
  db.Exec("PRAGMA wal_autocheckpoint = 0");
  db.CreateTables();
  db.AddTopic(1, "/chatter", "std_msgs/msg/String");
  for (int i = 0; i < 5; ++i) db.AddMessage(1, i, CdrString("w" + std::to_string(i)));
  ASSERT_GT(fs::file_size(path + "-wal"), 0u);
  const std::vector<ReadMessage> messages = ReadAll(OpenRosbag2Sqlite(path).get());
  ASSERT_EQ(messages.size(), 5u);
  EXPECT_EQ(DecodeCdrString(messages[4].data), "w4");
}

TEST(Rosbag2Sqlite, BadInput) {
  const std::string text = OutputFile("text.db3");
  test::WriteFile(text, "this is not a database at all, it is text\n");
  EXPECT_NE(ErrorReadingSqlite(text).find("text.db3: byte 0: not an SQLite database"),
            std::string::npos);

  const std::string no_tables = OutputFile("no_tables.db3");
  Db3Writer(no_tables).Exec("CREATE TABLE other(x INTEGER)");
  EXPECT_NE(ErrorReadingSqlite(no_tables).find("no_tables.db3: not a rosbag2 database: it has "
                                               "no table 'topics'"),
            std::string::npos)
      << ErrorReadingSqlite(no_tables);

  const std::string orphan = OutputFile("orphan.db3");
  {
    Db3Writer db(orphan);
    db.CreateTables();
    db.AddTopic(1, "/a", "std_msgs/msg/String");
    db.AddMessage(1, 1, "ok");
    db.AddMessage(5, 2, "lost");
  }
  EXPECT_NE(ErrorReadingSqlite(orphan).find("message 2 refers to topic id 5"), std::string::npos)
      << ErrorReadingSqlite(orphan);

  const std::string json = OutputFile("json.db3");
  {
    Db3Writer db(json);
    db.CreateTables();
    db.AddTopic(1, "/pose", "geometry_msgs/msg/Pose", "json");
  }
  EXPECT_NE(ErrorReadingSqlite(json).find("topic '/pose' has serialization format 'json'"),
            std::string::npos);
}

TEST(Rosbag2Sqlite, EveryTruncationIsRefused) {
  const std::string source = OutputFile("whole.db3");
  {
    Db3Writer db(source);
    db.CreateTables();
    db.AddTopic(1, "/chatter", "std_msgs/msg/String");
    for (int i = 0; i < 200; ++i) db.AddMessage(1, i, CdrString(std::string(100, 'a' + i % 26)));
  }
  std::ifstream in(source, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 8192u);
  int refused = 0;
  int steps = 0;
  for (size_t size = 0; size < bytes.size(); size += 1000) {
    const std::string path = OutputFile("prefix_" + std::to_string(size) + ".db3");
    test::WriteFile(path, bytes.substr(0, size));
    ++steps;
    try {
      const auto reader = OpenRosbag2Sqlite(path);
      EXPECT_EQ(ReadAll(reader.get()).size(), 200u) << "prefix of " << size << " bytes";
    } catch (const ParseError&) {
      ++refused;
    }
  }
  EXPECT_EQ(refused, steps);  // every page holds something the reader needs
}

// --- The real rosbag2 bags. ---

fs::path SharedBag(const std::string& relative) {
  return test::SharedDataDir("ros2_bags") / relative;
}

void ExpectTalker(BagReader* reader) {
  const std::vector<ReadMessage> messages = ReadAll(reader);
  // metadata.yaml: /topic 10, /rosout 10, /parameter_events 0; 20 in all.
  const std::map<std::string, uint64_t> expected = {{"/rosout", 10}, {"/topic", 10}};
  EXPECT_EQ(CountByTopic(messages), expected) << reader->path();
  EXPECT_EQ(IndexedCounts(*reader), expected) << reader->path();
  std::vector<std::string> texts;
  for (const ReadMessage& message : messages) {
    if (message.topic == "/topic") texts.push_back(DecodeCdrString(message.data));
  }
  ASSERT_EQ(texts.size(), 10u);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(texts[i], "Hello, world! " + std::to_string(i));
  ASSERT_FALSE(messages.empty());
  EXPECT_EQ(messages.front().log_time_ns, 1585866235112411371);              // starting_time
  EXPECT_EQ(messages.back().log_time_ns, 1585866235112411371 + 4531096768);  // + duration
}

TEST(Rosbag2RealBags, TalkerSqliteAsFileAndDirectory) {
  AUTOCAL_REQUIRE_SHARED_DATA(SharedBag("talker_sqlite3"));
  ExpectTalker(OpenRosbag2Sqlite(SharedBag("talker_sqlite3/talker.db3").string()).get());
  ExpectTalker(OpenRosbag2Directory(SharedBag("talker_sqlite3").string()).get());
}

TEST(Rosbag2RealBags, TalkerMcapDirectory) {
  AUTOCAL_REQUIRE_SHARED_DATA(SharedBag("talker_mcap"));
  const auto reader = OpenRosbag2Directory(SharedBag("talker_mcap").string());
  EXPECT_EQ(reader->connections().size(), 3u);  // /parameter_events has no message
  ExpectTalker(reader.get());
}

TEST(Rosbag2RealBags, CdrTestDirectory) {
  AUTOCAL_REQUIRE_SHARED_DATA(SharedBag("cdr_test"));
  const auto reader = OpenRosbag2Directory(SharedBag("cdr_test").string());
  const std::map<std::string, uint64_t> expected = {{"/array_topic", 4}, {"/test_topic", 3}};
  EXPECT_EQ(CountByTopic(ReadAll(reader.get())), expected);
  EXPECT_EQ(IndexedCounts(*reader), expected);
}

// Read as autocal_import reads its --input (OpenBag), which takes a directory without
// metadata.yaml as the directory reader does.
TEST(Rosbag2RealBags, SplitRecordingPartWithoutMetadata) {
  AUTOCAL_REQUIRE_SHARED_DATA(SharedBag("wbag"));
  const auto reader = OpenBag(SharedBag("wbag").string());
  EXPECT_EQ(reader->connections().size(), 8u);
  const std::vector<ReadMessage> messages = ReadAll(reader.get());
  EXPECT_EQ(messages.size(), 1246u);  // the file's Statistics record
  EXPECT_EQ(CountByTopic(messages), IndexedCounts(*reader));
  for (const ReadMessage& message : messages) EXPECT_NE(DecodeCdrString(message.data), "?");
}

// --- Directories written here. ---

std::string SplitFile(int first, int count, bool compress_messages = false) {
  McapWriter writer;
  const uint16_t schema = writer.AddSchema("std_msgs/msg/String");
  const uint16_t a = writer.AddChannel(schema, "/a");
  const uint16_t b = writer.AddChannel(schema, "/b");
  for (int i = first; i < first + count; ++i) {
    std::string data = CdrString("n" + std::to_string(i));
    if (compress_messages) {
      std::string frame(ZSTD_compressBound(data.size()), '\0');
      frame.resize(ZSTD_compress(frame.data(), frame.size(), data.data(), data.size(), 1));
      data = frame;
    }
    writer.AddMessage(i % 3 == 0 ? b : a, 1000 + i, data);
  }
  return writer.Finish();
}

std::string Metadata(const std::string& files, const std::string& topics,
                     const std::string& compression_mode = "") {
  return "rosbag2_bagfile_information:\n"
         "  version: 5\n"
         "  storage_identifier: mcap\n"
         "  duration:\n    nanoseconds: 9\n"
         "  starting_time:\n    nanoseconds_since_epoch: 1000\n"
         "  message_count: 10\n"
         "  topics_with_message_count:\n" +
         topics + "  compression_format: \"" + (compression_mode.empty() ? "" : "zstd") + "\"\n" +
         "  compression_mode: \"" + compression_mode + "\"\n" + "  relative_file_paths:\n" + files;
}

std::string Topic(const std::string& name, int count) {
  return "    - topic_metadata:\n        name: " + name +
         "\n        type: std_msgs/msg/String\n        serialization_format: cdr\n"
         "        offered_qos_profiles: \"\"\n      message_count: " +
         std::to_string(count) + "\n";
}

std::string MakeDirectory(const std::string& name) {
  const fs::path dir = test::OutputDir(name);
  return dir.string();
}

TEST(Rosbag2Directory, ReadsSplitFilesInOrder) {
  const std::string dir = MakeDirectory("split");
  test::WriteFile(dir + "/bag_0.mcap", SplitFile(0, 6));
  test::WriteFile(dir + "/bag_1.mcap", SplitFile(6, 4));
  test::WriteFile(dir + "/metadata.yaml", Metadata("    - bag_0.mcap\n    - bag_1.mcap\n",
                                                   Topic("/a", 6) + Topic("/b", 4)));
  const auto reader = OpenRosbag2Directory(dir);
  ASSERT_EQ(reader->connections().size(), 2u);
  const std::vector<ReadMessage> messages = ReadAll(reader.get());
  ASSERT_EQ(messages.size(), 10u);
  for (int i = 0; i < 10; ++i) {
    EXPECT_EQ(messages[i].topic, i % 3 == 0 ? "/b" : "/a");
    EXPECT_EQ(messages[i].log_time_ns, 1000 + i);
    EXPECT_EQ(DecodeCdrString(messages[i].data), "n" + std::to_string(i));
  }
  const auto indexed = reader->IndexedTopics();
  ASSERT_TRUE(indexed.has_value());
  EXPECT_EQ((*indexed)[0].message_count, 6u);
  EXPECT_EQ((*indexed)[0].first_log_time_ns, 1001);  // from the files' message indexes
  EXPECT_EQ((*indexed)[0].last_log_time_ns, 1008);
  EXPECT_EQ((*indexed)[1].message_count, 4u);
  EXPECT_EQ((*indexed)[1].last_log_time_ns, 1009);
}

TEST(Rosbag2Directory, WithoutMetadataOrdersFilesBySplitIndex) {
  const std::string dir = MakeDirectory("no_metadata");
  // bag_10 sorts before bag_2 as text; the split index puts it last.
  test::WriteFile(dir + "/bag_2.mcap", SplitFile(0, 5));
  test::WriteFile(dir + "/bag_10.mcap", SplitFile(5, 5));
  const auto reader = OpenRosbag2Directory(dir);
  const std::vector<ReadMessage> messages = ReadAll(reader.get());
  ASSERT_EQ(messages.size(), 10u);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(messages[i].log_time_ns, 1000 + i);
  const std::map<std::string, uint64_t> expected = {{"/a", 6}, {"/b", 4}};
  EXPECT_EQ(IndexedCounts(*reader), expected);
}

TEST(Rosbag2Directory, DecompressesPerMessageZstd) {
  const std::string dir = MakeDirectory("message_compression");
  test::WriteFile(dir + "/bag_0.mcap", SplitFile(0, 10, /*compress_messages=*/true));
  test::WriteFile(dir + "/metadata.yaml",
                  Metadata("    - bag_0.mcap\n", Topic("/a", 6) + Topic("/b", 4), "MESSAGE"));
  const std::vector<ReadMessage> messages = ReadAll(OpenRosbag2Directory(dir).get());
  ASSERT_EQ(messages.size(), 10u);
  EXPECT_EQ(DecodeCdrString(messages[7].data), "n7");
}

TEST(Rosbag2Directory, BadInput) {
  const std::string dir = MakeDirectory("bad");
  test::WriteFile(dir + "/bag_0.mcap", SplitFile(0, 6));
  const std::string metadata = dir + "/metadata.yaml";

  test::WriteFile(metadata,
                  Metadata("    - bag_0.mcap\n", Topic("/a", 6) + Topic("/b", 4), "FILE"));
  EXPECT_NE(ErrorReadingDirectory(dir).find("compression_mode FILE"), std::string::npos);

  test::WriteFile(metadata, Metadata("    - bag_0.mcap\n", Topic("/a", 6)));
  EXPECT_NE(ErrorReadingDirectory(dir).find("bag_0.mcap: topic '/b' is not in the directory's "
                                            "metadata.yaml"),
            std::string::npos)
      << ErrorReadingDirectory(dir);

  test::WriteFile(metadata, Metadata("    - bag_7.mcap\n", Topic("/a", 6)));
  EXPECT_NE(ErrorReadingDirectory(dir).find("the file 'bag_7.mcap' it lists is missing"),
            std::string::npos);

  test::WriteFile(metadata, "rosbag2_bagfile_information:\n  version: 5\n");
  EXPECT_NE(ErrorReadingDirectory(dir).find(
                "metadata.yaml:2:3: rosbag2_bagfile_information: missing required key "
                "'storage_identifier'"),
            std::string::npos)
      << ErrorReadingDirectory(dir);

  // Regression (fuzz_rosbag2_metadata): a scalar or a list where a map belongs made yaml-cpp
  // throw its own exception instead of a ParseError naming the place.
  test::WriteFile(metadata, "rosbag2_bagfile_information\n");
  EXPECT_NE(ErrorReadingDirectory(dir).find("metadata.yaml:1:1: metadata.yaml: expected a map"),
            std::string::npos)
      << ErrorReadingDirectory(dir);
  test::WriteFile(metadata, Metadata("    - bag_0.mcap\n", "    - /a\n"));
  EXPECT_NE(ErrorReadingDirectory(dir).find("topics_with_message_count[0]: expected a map"),
            std::string::npos)
      << ErrorReadingDirectory(dir);

  // A recording whose end, start plus duration, is no time.
  std::string metadata_text = Metadata("    - bag_0.mcap\n", Topic("/a", 6) + Topic("/b", 4));
  metadata_text.replace(metadata_text.find("nanoseconds: 9"), 14, "nanoseconds: -9");
  test::WriteFile(metadata, metadata_text);
  EXPECT_NE(ErrorReadingDirectory(dir).find(
                "metadata.yaml:5:18: rosbag2_bagfile_information.duration.nanoseconds: expected a "
                "duration of 0 or more"),
            std::string::npos)
      << ErrorReadingDirectory(dir);
  metadata_text.replace(metadata_text.find("nanoseconds: -9"), 15, "nanoseconds: 9");
  metadata_text.replace(metadata_text.find("nanoseconds_since_epoch: 1000"), 29,
                        "nanoseconds_since_epoch: 9223372036854775807");
  test::WriteFile(metadata, metadata_text);
  EXPECT_NE(ErrorReadingDirectory(dir).find("ends before the year 2262, got 9"), std::string::npos)
      << ErrorReadingDirectory(dir);

  // A truncated file of the bag.
  test::WriteFile(metadata, Metadata("    - bag_0.mcap\n", Topic("/a", 6) + Topic("/b", 4)));
  test::WriteFile(dir + "/bag_0.mcap", SplitFile(0, 6).substr(0, 300));
  EXPECT_NE(ErrorReadingDirectory(dir).find("bag_0.mcap: byte 300: the file does not end"),
            std::string::npos);
}

// A directory that holds no bag is named as such when given as a bag.
TEST(Rosbag2Directory, ADirectoryWithoutABagIsRefused) {
  const std::string dir = MakeDirectory("no_bag");
  test::WriteFile(dir + "/notes.txt", "not a bag\n");
  try {
    OpenBag(dir);
    ADD_FAILURE() << "a directory without a bag was opened";
  } catch (const Error& error) {
    EXPECT_EQ(std::string(error.what()),
              "'" + dir + "' is not a rosbag2 directory: no metadata.yaml, no .mcap or .db3 file");
  }
}

}  // namespace
}  // namespace import
}  // namespace autocal
