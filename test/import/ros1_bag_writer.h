#pragma once

// A small ROS 1 bag (format 2.0) writer for tests and benchmarks: the magic line, the bag
// header record (padded to 4096 bytes as rosbag does), chunks of connection and message
// data records (uncompressed, bz2 or lz4 frames), an index data record per connection
// after each chunk, and at index_pos the connection and chunk info records. An unindexed
// bag has index_pos 0 and no index records; Unfinished() and StoppedInChunk() give the bags a
// recorder that stopped without closing the bag leaves.
// Written from the published format description, independently of the reader under test.

#include <bzlib.h>
#include <lz4frame.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace autocal {
namespace test {

class Ros1BagWriter {
 public:
  enum class Compression { kNone, kBz2, kLz4 };
  struct Options {
    Compression compression = Compression::kNone;
    size_t chunk_bytes = 64 * 1024;  // a chunk is closed once its records exceed this
    bool indexed = true;
    bool chunk_infos = true;  // false: index_pos set, but the chunk info records missing
  };

  Ros1BagWriter() : Ros1BagWriter(Options()) {}
  explicit Ros1BagWriter(Options options) : options_(options) {
    out_ = "#ROSBAG V2.0\n";
    header_pos_ = out_.size();
    WriteBagHeader(0, 0, 0);
  }

  uint32_t AddConnection(const std::string& topic, const std::string& type) {
    const uint32_t id = static_cast<uint32_t>(connections_.size());
    connections_.push_back({topic, type});
    return id;
  }

  void Write(uint32_t connection, int64_t time_ns, std::string_view data) {
    if (chunk_connections_.insert(connection).second) {
      chunk_.append(ConnectionRecord(connection));
    }
    const uint32_t offset = static_cast<uint32_t>(chunk_.size());
    std::string header = Field("op", std::string(1, '\x02')) + Field("conn", U32(connection)) +
                         Field("time", Time(time_ns));
    chunk_.append(Record(header, data));
    chunk_index_[connection].push_back({time_ns, offset});
    if (chunk_start_ns_ < 0 || time_ns < chunk_start_ns_) chunk_start_ns_ = time_ns;
    if (time_ns > chunk_end_ns_) chunk_end_ns_ = time_ns;
    if (chunk_.size() >= options_.chunk_bytes) CloseChunk();
  }

  // The whole bag.
  std::string Finish() {
    CloseChunk();
    if (!options_.indexed) return out_;
    const uint64_t index_pos = out_.size();
    for (uint32_t id = 0; id < connections_.size(); ++id) out_.append(ConnectionRecord(id));
    for (const ChunkInfo& info : chunk_infos_) {
      if (!options_.chunk_infos) break;
      std::string header = Field("op", std::string(1, '\x06')) + Field("ver", U32(1)) +
                           Field("chunk_pos", U64(info.position)) +
                           Field("start_time", Time(info.start_ns)) +
                           Field("end_time", Time(info.end_ns)) +
                           Field("count", U32(static_cast<uint32_t>(info.counts.size())));
      std::string data;
      for (const auto& [conn, count] : info.counts) data += U32(conn) + U32(count);
      out_.append(Record(header, data));
    }
    const size_t end = out_.size();
    std::string tail = out_.substr(header_pos_ + bag_header_bytes_);
    out_.resize(header_pos_);
    WriteBagHeader(index_pos, static_cast<uint32_t>(connections_.size()),
                   static_cast<uint32_t>(chunk_infos_.size()));
    out_ += tail;
    if (out_.size() != end) throw std::logic_error("bag header changed size");
    return out_;
  }

  // The bytes written so far: where the next chunk will start.
  size_t size() const { return out_.size(); }

  // Closes the chunk being written now, whatever its size.
  void EndChunk() { CloseChunk(); }

  // The bag a recorder leaves when it stops right after closing a chunk: every chunk closed
  // with its index data records, no index, index_pos 0.
  std::string Unfinished() {
    CloseChunk();
    return out_;
  }

  // The bag a recorder leaves when it stops with a chunk open: rosbag writes the chunk's
  // header with the placeholder sizes 0 and 0 (patched when it closes the chunk) and then the
  // chunk's data as it comes; here the first `kept_bytes` of that data, compressed as the
  // options say.
  std::string StoppedInChunk(size_t kept_bytes) {
    const std::string header = Field("op", std::string(1, '\x05')) +
                               Field("compression", CompressionName()) + Field("size", U32(0));
    const std::string data = Compressed(chunk_);
    return out_ + U32(static_cast<uint32_t>(header.size())) + header + U32(0) +
           data.substr(0, kept_bytes);
  }

  static void WriteFile(const std::string& path, const std::string& bytes) {
    std::ofstream file(path, std::ios::binary | std::ios::trunc);
    file.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!file) throw std::runtime_error("cannot write " + path);
  }

  // Helpers to build records by hand (bad-input tests).
  static std::string U32(uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); }
  static std::string U64(uint64_t v) { return std::string(reinterpret_cast<const char*>(&v), 8); }
  static std::string Time(int64_t ns) {
    return U32(static_cast<uint32_t>(ns / 1000000000)) +
           U32(static_cast<uint32_t>(ns % 1000000000));
  }
  static std::string Field(const std::string& name, const std::string& value) {
    return U32(static_cast<uint32_t>(name.size() + 1 + value.size())) + name + "=" + value;
  }
  static std::string Record(const std::string& header, std::string_view data) {
    return U32(static_cast<uint32_t>(header.size())) + header +
           U32(static_cast<uint32_t>(data.size())) + std::string(data);
  }

  static std::string Bz2(const std::string& raw) {
    unsigned int size = static_cast<unsigned int>(raw.size() + raw.size() / 100 + 600);
    std::string out(size, '\0');
    if (BZ2_bzBuffToBuffCompress(out.data(), &size, const_cast<char*>(raw.data()),
                                 static_cast<unsigned int>(raw.size()), 9, 0, 0) != BZ_OK) {
      throw std::runtime_error("bz2 compression failed");
    }
    out.resize(size);
    return out;
  }
  // An LZ4 frame with a content checksum and independent blocks, as roslz4 writes them.
  static std::string Lz4(const std::string& raw) {
    LZ4F_preferences_t preferences;
    std::memset(&preferences, 0, sizeof(preferences));
    preferences.frameInfo.blockMode = LZ4F_blockIndependent;
    preferences.frameInfo.contentChecksumFlag = LZ4F_contentChecksumEnabled;
    std::string out(LZ4F_compressFrameBound(raw.size(), &preferences), '\0');
    const size_t size =
        LZ4F_compressFrame(out.data(), out.size(), raw.data(), raw.size(), &preferences);
    if (LZ4F_isError(size)) throw std::runtime_error("lz4 compression failed");
    out.resize(size);
    return out;
  }

 private:
  struct ConnectionInfo {
    std::string topic;
    std::string type;
  };
  struct ChunkInfo {
    uint64_t position = 0;
    int64_t start_ns = 0;
    int64_t end_ns = 0;
    std::map<uint32_t, uint32_t> counts;
  };

  void WriteBagHeader(uint64_t index_pos, uint32_t connections, uint32_t chunks) {
    const std::string header =
        Field("op", std::string(1, '\x03')) + Field("index_pos", U64(index_pos)) +
        Field("conn_count", U32(connections)) + Field("chunk_count", U32(chunks));
    const size_t padding = 4096 - header.size() - 8 - (out_.size() - header_pos_);
    out_.append(Record(header, std::string(padding, ' ')));
    bag_header_bytes_ = 4096;
  }

  std::string ConnectionRecord(uint32_t id) const {
    const ConnectionInfo& c = connections_.at(id);
    const std::string header =
        Field("op", std::string(1, '\x07')) + Field("conn", U32(id)) + Field("topic", c.topic);
    const std::string data = Field("topic", c.topic) + Field("type", c.type) +
                             Field("md5sum", "*") + Field("message_definition", "");
    return Record(header, data);
  }

  const char* CompressionName() const {
    const char* names[] = {"none", "bz2", "lz4"};
    return names[static_cast<int>(options_.compression)];
  }
  std::string Compressed(const std::string& raw) const {
    return options_.compression == Compression::kNone  ? raw
           : options_.compression == Compression::kBz2 ? Bz2(raw)
                                                       : Lz4(raw);
  }

  void CloseChunk() {
    if (chunk_.empty()) return;
    const std::string data = Compressed(chunk_);
    ChunkInfo info;
    info.position = out_.size();
    info.start_ns = chunk_start_ns_;
    info.end_ns = chunk_end_ns_;
    const std::string header = Field("op", std::string(1, '\x05')) +
                               Field("compression", CompressionName()) +
                               Field("size", U32(static_cast<uint32_t>(chunk_.size())));
    out_.append(Record(header, data));
    for (const auto& [conn, entries] : chunk_index_) {
      info.counts[conn] = static_cast<uint32_t>(entries.size());
      if (!options_.indexed) continue;
      std::string index = Field("op", std::string(1, '\x04')) + Field("ver", U32(1)) +
                          Field("conn", U32(conn)) +
                          Field("count", U32(static_cast<uint32_t>(entries.size())));
      std::string entries_data;
      for (const auto& [time_ns, offset] : entries) entries_data += Time(time_ns) + U32(offset);
      out_.append(Record(index, entries_data));
    }
    chunk_infos_.push_back(info);
    chunk_.clear();
    chunk_connections_.clear();
    chunk_index_.clear();
    chunk_start_ns_ = -1;
    chunk_end_ns_ = -1;
  }

  Options options_;
  std::string out_;
  size_t header_pos_ = 0;
  size_t bag_header_bytes_ = 0;
  std::vector<ConnectionInfo> connections_;
  std::string chunk_;
  std::set<uint32_t> chunk_connections_;
  std::map<uint32_t, std::vector<std::pair<int64_t, uint32_t>>> chunk_index_;
  int64_t chunk_start_ns_ = -1;
  int64_t chunk_end_ns_ = -1;
  std::vector<ChunkInfo> chunk_infos_;
};

}  // namespace test
}  // namespace autocal
