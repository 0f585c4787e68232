// rosbag2's SQLite storage (.db3) as a BagReader: the topics table gives the connections,
// the messages table the messages in timestamp order through one streaming statement (the
// timestamp index makes it an index walk: memory stays bounded whatever the bag's size).

#include <sqlite3.h>
#include <sys/stat.h>

#include <cstdio>
#include <fstream>
#include <limits>
#include <unordered_map>

#include "autocal/common/error.h"
#include "import/bag_reader.h"

namespace autocal {
namespace import {
namespace {

// "file:<path>?mode=ro[&immutable=1]" with the URI's reserved characters escaped.
std::string ReadOnlyUri(const std::string& path, bool immutable) {
  std::string uri = "file:";
  for (const char c : path) {
    if (c == '?' || c == '#' || c == '%') {
      char escaped[4];
      std::snprintf(escaped, sizeof(escaped), "%%%02X", static_cast<unsigned char>(c));
      uri += escaped;
    } else {
      uri += c;
    }
  }
  return uri + (immutable ? "?mode=ro&immutable=1" : "?mode=ro");
}

bool NonEmptyFileExists(const std::string& path) {
  struct stat info {};
  return ::stat(path.c_str(), &info) == 0 && info.st_size > 0;
}

// The connection; closed after its statements, whatever order they are finalized in
// (sqlite3_close_v2), also when the reader's constructor throws.
class Database {
 public:
  Database() = default;
  ~Database() { sqlite3_close_v2(db_); }
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;
  sqlite3** out() { return &db_; }
  sqlite3* get() const { return db_; }

 private:
  sqlite3* db_ = nullptr;
};

class Statement {
 public:
  Statement() = default;
  ~Statement() { sqlite3_finalize(statement_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  sqlite3_stmt** out() { return &statement_; }
  sqlite3_stmt* get() const { return statement_; }

 private:
  sqlite3_stmt* statement_ = nullptr;
};

class Rosbag2SqliteReader final : public BagReader {
 public:
  explicit Rosbag2SqliteReader(const std::string& path);

  const std::string& path() const override { return path_; }
  const std::vector<Connection>& connections() const override { return connections_; }
  std::optional<std::vector<IndexedTopic>> IndexedTopics() const override;
  bool Next(BagMessage* message) override;

 private:
  [[noreturn]] void Fail(const std::string& message) const {
    throw ParseError({path_, 0, 0, -1}, message);
  }
  void Prepare(const char* sql, Statement* statement) const;
  void CheckTables() const;
  void ReadTopics();

  std::string path_;
  Database database_;      // before the statements: destroyed after them
  sqlite3* db_ = nullptr;  // database_.get()
  std::vector<Connection> connections_;
  std::unordered_map<int64_t, uint32_t> connection_of_topic_id_;
  Statement messages_;
  bool done_ = false;
};

Rosbag2SqliteReader::Rosbag2SqliteReader(const std::string& path) : path_(path) {
  std::ifstream probe(path, std::ios::binary);
  if (!probe) throw Error("cannot open '" + path + "' for reading");
  char magic[16] = {};
  probe.read(magic, sizeof(magic));
  if (probe.gcount() != 16 || std::string(magic, 16) != std::string("SQLite format 3\0", 16)) {
    throw ParseError({path_, 0, 0, 0}, "not an SQLite database (no 'SQLite format 3' header)");
  }
  // Bags are read where they lie, often on read-only storage: immutable tells SQLite not to
  // look for locks or a journal. A bag left with a write-ahead log is read through it instead.
  const bool immutable = !NonEmptyFileExists(path + "-wal");
  const int opened = sqlite3_open_v2(ReadOnlyUri(path, immutable).c_str(), database_.out(),
                                     SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr);
  db_ = database_.get();
  if (opened != SQLITE_OK) {
    Fail(std::string("cannot open the SQLite database: ") + sqlite3_errmsg(db_));
  }
  CheckTables();
  ReadTopics();
  Prepare("SELECT topic_id, timestamp, data, id FROM messages ORDER BY timestamp, id", &messages_);
}

void Rosbag2SqliteReader::Prepare(const char* sql, Statement* statement) const {
  if (sqlite3_prepare_v2(db_, sql, -1, statement->out(), nullptr) != SQLITE_OK) {
    Fail(std::string("SQLite: ") + sqlite3_errmsg(db_) + " (in: " + sql + ")");
  }
}

void Rosbag2SqliteReader::CheckTables() const {
  for (const char* table : {"topics", "messages"}) {
    Statement statement;
    Prepare("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?", &statement);
    sqlite3_bind_text(statement.get(), 1, table, -1, SQLITE_STATIC);
    const int result = sqlite3_step(statement.get());
    if (result == SQLITE_DONE) {
      Fail(std::string("not a rosbag2 database: it has no table '") + table + "'");
    }
    if (result != SQLITE_ROW) Fail(std::string("SQLite: ") + sqlite3_errmsg(db_));
  }
}

void Rosbag2SqliteReader::ReadTopics() {
  Statement topics;
  Prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id", &topics);
  int result;
  while ((result = sqlite3_step(topics.get())) == SQLITE_ROW) {
    const int64_t topic_id = sqlite3_column_int64(topics.get(), 0);
    const auto text = [&](int column) {
      const unsigned char* value = sqlite3_column_text(topics.get(), column);
      return value == nullptr ? std::string() : std::string(reinterpret_cast<const char*>(value));
    };
    Connection connection;
    connection.topic = text(1);
    connection.type = text(2);
    const std::string format = text(3);
    if (format != "cdr") {
      Fail("topic '" + connection.topic + "' has serialization format '" + format +
           "': only cdr is read");
    }
    connection.serialization = Serialization::kCdr;
    if (topic_id < 0 || topic_id > std::numeric_limits<uint32_t>::max()) {
      Fail("topic '" + connection.topic + "' has the id " + std::to_string(topic_id) +
           ", outside 0 to 2^32 - 1");
    }
    connection.id = static_cast<uint32_t>(topic_id);
    connection_of_topic_id_[topic_id] = connection.id;
    connections_.push_back(connection);
  }
  if (result != SQLITE_DONE) Fail(std::string("SQLite, reading topics: ") + sqlite3_errmsg(db_));
}

std::optional<std::vector<IndexedTopic>> Rosbag2SqliteReader::IndexedTopics() const {
  std::unordered_map<int64_t, IndexedTopic> by_topic;
  Statement statement;
  Prepare(
      "SELECT topic_id, COUNT(*), MIN(timestamp), MAX(timestamp) FROM messages GROUP BY topic_id",
      &statement);
  int result;
  while ((result = sqlite3_step(statement.get())) == SQLITE_ROW) {
    IndexedTopic& topic = by_topic[sqlite3_column_int64(statement.get(), 0)];
    topic.message_count = static_cast<uint64_t>(sqlite3_column_int64(statement.get(), 1));
    topic.first_log_time_ns = sqlite3_column_int64(statement.get(), 2);
    topic.last_log_time_ns = sqlite3_column_int64(statement.get(), 3);
  }
  if (result != SQLITE_DONE) Fail(std::string("SQLite, counting messages: ") + sqlite3_errmsg(db_));
  std::vector<IndexedTopic> topics;
  for (const Connection& connection : connections_) {
    IndexedTopic topic = by_topic[connection.id];
    topic.connection_id = connection.id;
    topics.push_back(topic);
  }
  return topics;
}

bool Rosbag2SqliteReader::Next(BagMessage* message) {
  if (done_) return false;
  sqlite3_stmt* statement = messages_.get();
  const int result = sqlite3_step(statement);
  if (result == SQLITE_DONE) {
    done_ = true;
    return false;
  }
  if (result != SQLITE_ROW) Fail(std::string("SQLite, reading messages: ") + sqlite3_errmsg(db_));
  const int64_t row_id = sqlite3_column_int64(statement, 3);
  const int64_t topic_id = sqlite3_column_int64(statement, 0);
  const auto connection = connection_of_topic_id_.find(topic_id);
  if (connection == connection_of_topic_id_.end()) {
    Fail("message " + std::to_string(row_id) + " refers to topic id " + std::to_string(topic_id) +
         ", which the topics table does not list");
  }
  const void* data = sqlite3_column_blob(statement, 2);
  const int size = sqlite3_column_bytes(statement, 2);
  message->connection_id = connection->second;
  message->log_time_ns = sqlite3_column_int64(statement, 1);
  message->data =
      data == nullptr ? std::string_view() : std::string_view(static_cast<const char*>(data), size);
  // No byte offsets in a database: the message's row id stands in for one.
  message->file_offset = static_cast<uint64_t>(row_id);
  return true;
}

}  // namespace

std::unique_ptr<BagReader> OpenRosbag2Sqlite(const std::string& path) {
  return std::make_unique<Rosbag2SqliteReader>(path);
}

}  // namespace import
}  // namespace autocal
