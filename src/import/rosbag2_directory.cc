// A rosbag2 directory as one BagReader: its storage files (MCAP or SQLite) read one after
// the other in recording order, their connections merged by topic. metadata.yaml names the
// files and topics and gives the counts; without it (a copied part of a split recording)
// the directory's .mcap / .db3 files are taken in the order of their _N suffix.

#include <zstd.h>

#include <algorithm>
#include <filesystem>
#include <unordered_map>

#include "autocal/common/error.h"
#include "import/bag_reader.h"
#include "import/mcap_decompress.h"
#include "import/rosbag2_metadata.h"

namespace autocal {
namespace import {
namespace {

namespace fs = std::filesystem;
using internal::Rosbag2Metadata;

// Per-message zstd frames larger than this are refused before allocation.
constexpr unsigned long long kMaxMessageBytes = 1ull << 30;

// "bag_12.mcap" -> ("bag", 12): the split index rosbag2 appends; -1 without one.
std::pair<std::string, long> SplitIndex(const fs::path& file) {
  const std::string stem = file.stem().string();
  const size_t underscore = stem.rfind('_');
  if (underscore == std::string::npos || underscore + 1 == stem.size()) return {stem, -1};
  const std::string digits = stem.substr(underscore + 1);
  if (digits.size() > 9 ||
      !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return {stem, -1};
  return {stem.substr(0, underscore), std::stol(digits)};
}

class Rosbag2DirectoryReader final : public BagReader {
 public:
  explicit Rosbag2DirectoryReader(const std::string& dir);

  const std::string& path() const override { return dir_; }
  const std::vector<Connection>& connections() const override { return connections_; }
  std::optional<std::vector<IndexedTopic>> IndexedTopics() const override;
  bool Next(BagMessage* message) override;

 private:
  void UseMetadata(const Rosbag2Metadata& metadata, const std::string& metadata_path);
  void FindStorageFiles();
  std::unique_ptr<BagReader> OpenFile(const std::string& file) const;
  // The connection of `topic` (of `type` when given), added when `add`.
  uint32_t ConnectionOf(const BagReader& file, const Connection& connection, bool add);
  bool OpenNextFile();
  void Decompress(BagMessage* message);

  std::string dir_;
  std::string storage_;  // "mcap" or "sqlite3"
  std::vector<std::string> files_;
  std::vector<Connection> connections_;
  std::unordered_map<std::string, uint32_t> by_topic_;  // index into connections_
  std::optional<Rosbag2Metadata> metadata_;
  bool compressed_messages_ = false;

  size_t next_file_ = 0;
  std::unique_ptr<BagReader> current_;
  std::unordered_map<uint32_t, uint32_t> current_ids_;  // file connection id -> ours
  internal::Decompressor decompressor_;
  internal::ByteBuffer message_buffer_;
};

Rosbag2DirectoryReader::Rosbag2DirectoryReader(const std::string& dir) : dir_(dir) {
  if (!fs::is_directory(dir_)) throw Error("'" + dir_ + "' is not a directory");
  const fs::path metadata_path = fs::path(dir_) / "metadata.yaml";
  if (fs::exists(metadata_path)) {
    UseMetadata(internal::ReadRosbag2Metadata(metadata_path.string()), metadata_path.string());
  } else {
    FindStorageFiles();
  }
}

void Rosbag2DirectoryReader::UseMetadata(const Rosbag2Metadata& metadata,
                                         const std::string& metadata_path) {
  const auto fail = [&](const std::string& message) {
    throw ParseError({metadata_path, 0, 0, -1}, message);
  };
  storage_ = metadata.storage_identifier;
  if (storage_ != "mcap" && storage_ != "sqlite3") {
    fail("storage_identifier '" + storage_ + "': only mcap and sqlite3 bags are read");
  }
  const std::string& mode = metadata.compression_mode;
  if (mode == "FILE") {
    fail("the bag's files are compressed whole (compression_mode FILE, " +
         metadata.compression_format +
         "), which is not read: decompress them first (ros2 bag convert, or zstd -d)");
  }
  compressed_messages_ = mode == "MESSAGE";
  if (compressed_messages_ && metadata.compression_format != "zstd") {
    fail("compression_mode MESSAGE with compression_format '" + metadata.compression_format +
         "': only zstd is read");
  }
  if (!mode.empty() && mode != "NONE" && mode != "MESSAGE") {
    fail("unknown compression_mode '" + mode + "'");
  }
  for (const std::string& relative : metadata.relative_files) {
    fs::path file = fs::path(dir_) / relative;
    // Early rosbag2 versions wrote the paths with the bag directory's name in front.
    if (!fs::exists(file)) file = fs::path(dir_) / fs::path(relative).filename();
    if (!fs::exists(file)) fail("the file '" + relative + "' it lists is missing");
    files_.push_back(file.string());
  }
  if (files_.empty()) fail("relative_file_paths lists no file");
  for (const internal::Rosbag2Topic& topic : metadata.topics) {
    if (topic.serialization_format != "cdr") {
      fail("topic '" + topic.name + "' has serialization_format '" + topic.serialization_format +
           "': only cdr is read");
    }
    if (by_topic_.count(topic.name) != 0) fail("topic '" + topic.name + "' is listed twice");
    by_topic_[topic.name] = static_cast<uint32_t>(connections_.size());
    connections_.push_back({static_cast<uint32_t>(connections_.size() + 1), topic.name, topic.type,
                            Serialization::kCdr});
  }
  metadata_ = metadata;
}

void Rosbag2DirectoryReader::FindStorageFiles() {
  std::vector<fs::path> found;
  for (const auto& entry : fs::directory_iterator(dir_)) {
    const std::string extension = entry.path().extension().string();
    if (entry.is_regular_file() && (extension == ".mcap" || extension == ".db3")) {
      found.push_back(entry.path());
    }
  }
  if (found.empty()) {
    throw Error("'" + dir_ +
                "' is not a rosbag2 directory: no metadata.yaml, no .mcap or .db3 file");
  }
  std::sort(found.begin(), found.end(),
            [](const fs::path& a, const fs::path& b) { return SplitIndex(a) < SplitIndex(b); });
  for (const fs::path& file : found) {
    const std::string storage = file.extension() == ".mcap" ? "mcap" : "sqlite3";
    if (!storage_.empty() && storage != storage_) {
      throw Error("'" + dir_ + "' holds both .mcap and .db3 files and no metadata.yaml");
    }
    storage_ = storage;
    files_.push_back(file.string());
  }
  // Without metadata, the connections are the union of the files' own.
  for (const std::string& file : files_) {
    const auto reader = OpenFile(file);
    for (const Connection& connection : reader->connections()) {
      ConnectionOf(*reader, connection, /*add=*/true);
    }
  }
}

std::unique_ptr<BagReader> Rosbag2DirectoryReader::OpenFile(const std::string& file) const {
  return storage_ == "mcap" ? OpenMcap(file) : OpenRosbag2Sqlite(file);
}

uint32_t Rosbag2DirectoryReader::ConnectionOf(const BagReader& file, const Connection& connection,
                                              bool add) {
  const auto known = by_topic_.find(connection.topic);
  if (known == by_topic_.end()) {
    if (!add) {
      throw ParseError({file.path(), 0, 0, -1},
                       "topic '" + connection.topic + "' is not in the directory's metadata.yaml");
    }
    by_topic_[connection.topic] = static_cast<uint32_t>(connections_.size());
    Connection merged = connection;
    merged.id = static_cast<uint32_t>(connections_.size() + 1);
    connections_.push_back(merged);
    return merged.id;
  }
  const Connection& ours = connections_[known->second];
  if (!connection.type.empty() && connection.type != ours.type) {
    throw ParseError({file.path(), 0, 0, -1},
                     "topic '" + connection.topic + "' has type " + connection.type + " here and " +
                         ours.type + " in " + (metadata_ ? "metadata.yaml" : "an earlier file"));
  }
  return ours.id;
}

bool Rosbag2DirectoryReader::OpenNextFile() {
  if (next_file_ == files_.size()) {
    current_.reset();
    return false;
  }
  current_ = OpenFile(files_[next_file_++]);
  current_ids_.clear();
  for (const Connection& connection : current_->connections()) {
    current_ids_[connection.id] = ConnectionOf(*current_, connection, /*add=*/false);
  }
  return true;
}

bool Rosbag2DirectoryReader::Next(BagMessage* message) {
  while (current_ != nullptr || next_file_ < files_.size()) {
    if (current_ == nullptr && !OpenNextFile()) return false;
    if (current_->Next(message)) {
      message->connection_id = current_ids_.at(message->connection_id);
      if (compressed_messages_) Decompress(message);
      return true;
    }
    current_.reset();
  }
  return false;
}

// compression_mode MESSAGE: each message is one zstd frame that declares its size.
void Rosbag2DirectoryReader::Decompress(BagMessage* message) {
  const auto fail = [&](const std::string& why) {
    throw ParseError({current_->path(), 0, 0, static_cast<int64_t>(message->file_offset)},
                     "compressed message: " + why);
  };
  const unsigned long long size =
      ZSTD_getFrameContentSize(message->data.data(), message->data.size());
  if (size == ZSTD_CONTENTSIZE_ERROR) fail("not a zstd frame");
  if (size == ZSTD_CONTENTSIZE_UNKNOWN) fail("the zstd frame does not declare its size");
  if (size > kMaxMessageBytes) fail("it declares " + std::to_string(size) + " bytes");
  char* out = message_buffer_.Reserve(size);
  const std::string error = decompressor_.Decompress("zstd", message->data, out, size);
  if (!error.empty()) fail(error);
  message->data = std::string_view(out, size);
}

// Counts from metadata.yaml (else the sum of the files' own indexes); first and last log
// times from the files' indexes, else the bag's start and end.
std::optional<std::vector<IndexedTopic>> Rosbag2DirectoryReader::IndexedTopics() const {
  std::vector<IndexedTopic> merged(connections_.size());
  bool files_indexed = true;
  for (const std::string& file : files_) {
    const auto reader = OpenFile(file);
    const auto indexed = reader->IndexedTopics();
    if (!indexed) {
      files_indexed = false;
      break;
    }
    std::unordered_map<uint32_t, std::string> topic_of;
    for (const Connection& connection : reader->connections()) {
      topic_of[connection.id] = connection.topic;
    }
    for (const IndexedTopic& topic : *indexed) {
      const auto ours = by_topic_.find(topic_of[topic.connection_id]);
      if (ours == by_topic_.end() || topic.message_count == 0) continue;
      IndexedTopic& sum = merged[ours->second];
      sum.first_log_time_ns = sum.message_count == 0
                                  ? topic.first_log_time_ns
                                  : std::min(sum.first_log_time_ns, topic.first_log_time_ns);
      sum.last_log_time_ns = std::max(sum.last_log_time_ns, topic.last_log_time_ns);
      sum.message_count += topic.message_count;
    }
  }
  if (!files_indexed && !metadata_) return std::nullopt;
  for (size_t i = 0; i < connections_.size(); ++i) {
    IndexedTopic& topic = merged[i];
    topic.connection_id = connections_[i].id;
    if (!metadata_) continue;
    topic.message_count = metadata_->topics[i].message_count;
    if (!files_indexed && topic.message_count > 0) {
      topic.first_log_time_ns = metadata_->starting_time_ns;
      topic.last_log_time_ns = metadata_->starting_time_ns + metadata_->duration_ns;
    }
  }
  return merged;
}

}  // namespace

std::unique_ptr<BagReader> OpenRosbag2Directory(const std::string& dir) {
  return std::make_unique<Rosbag2DirectoryReader>(dir);
}

}  // namespace import
}  // namespace autocal
