// ROS 1 bag format 2.0 (docs/import.md, "ROS 1 bags"). A bag is the line "#ROSBAG V2.0\n"
// followed by records, each
//   u32 header_len, header (fields: u32 field_len, "name=value"), u32 data_len, data.
// The header field "op" says the record's kind: 0x03 bag header (index_pos, conn_count,
// chunk_count), 0x05 chunk (compression, size; its data holds connection and message
// records), 0x04 index data (after each chunk), 0x07 connection, 0x06 chunk info, 0x02
// message data (conn, time). Connections and chunk infos follow index_pos.
//
// Messages are read by one linear pass over the chunks, one chunk in memory at a time. The
// index (connection records, chunk infos, index data records) gives the connections up
// front and IndexedTopics(); a bag without one (index_pos 0, or chunk infos missing, as a
// recorder killed mid-write leaves it) is first scanned for its connections, and has no
// IndexedTopics() (callers warn).
//
// A recorder that stops without closing the bag (killed, out of power) leaves index_pos 0 and
// its last chunk open: rosbag writes a chunk's header with the placeholder sizes 0 and 0 and
// patches them when it closes the chunk, so that chunk's data runs to the file's end, and its
// last record may be cut short. In a bag with index_pos 0 the scan reads such a chunk (or a
// last record cut by the file's end) as far as its data holds whole records, and says what
// it left in Warnings().

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "import/bag_reader.h"
#include "import/chunk_decompression.h"
#include "import/ros1_records.h"

namespace autocal {
namespace import {
namespace ros1 {
namespace {

constexpr const char* kBadTime = "has nanoseconds of 1e9 or more (not a time)";

class Ros1BagReader final : public BagReader {
 public:
  explicit Ros1BagReader(std::string path);

  const std::string& path() const override { return path_; }
  const std::vector<Connection>& connections() const override { return connections_; }
  std::optional<std::vector<IndexedTopic>> IndexedTopics() const override { return indexed_; }
  bool Next(BagMessage* message) override;
  std::vector<std::string> Warnings() const override { return warnings_; }

 private:
  // One top-level record: where it starts, its header and where its data lies.
  struct Record {
    uint64_t offset = 0;
    int op = -1;
    HeaderFields fields;
    uint64_t data_offset = 0;
    uint32_t data_bytes = 0;
    uint64_t end = 0;  // offset of the next record
  };

  [[noreturn]] void Fail(uint64_t offset, const std::string& message) const;
  void ReadAt(uint64_t offset, size_t bytes, char* out, uint64_t record_offset,
              const std::string& what) const;
  // Reads the record at `offset` (header parsed, data not read). A record that runs past the
  // file's end is refused, or with `cut_ok` returned as false: record->op is the record's
  // kind when its header is whole, else -1.
  bool ReadRecord(uint64_t offset, Record* record, bool cut_ok = false);
  template <typename T>
  T Field(const Record& record, const char* name) const;
  std::string StringField(const HeaderFields& fields, uint64_t offset, int op,
                          const char* name) const;

  void ReadBagHeader();
  bool ReadIndex();
  void ReadChunkIndexes(const std::vector<uint64_t>& chunk_positions);
  void AddConnection(const HeaderFields& record_fields, std::string_view data, uint64_t offset,
                     int op);
  void LoadChunk(const Record& record);
  // The chunk a stopped recorder left open, its data from record.data_offset to the file's end.
  void LoadOpenChunk(const Record& record);
  // Whether `record` is that open chunk: a chunk with rosbag's placeholder sizes 0 and 0.
  bool IsOpenChunk(const Record& record) const;
  // The next message inside the loaded chunk; false when the chunk is used up.
  bool NextInChunk(BagMessage* message);
  void Rewind();

  std::string path_;
  FileDescriptor fd_;
  uint64_t file_bytes_ = 0;
  uint64_t index_pos_ = 0;
  uint32_t declared_connections_ = 0;
  uint32_t declared_chunks_ = 0;
  uint64_t records_begin_ = 0;  // first record after the bag header
  uint64_t records_end_ = 0;    // index_pos, or the file's end without an index
  std::vector<std::string> warnings_;

  std::vector<Connection> connections_;
  std::map<uint32_t, size_t> connection_index_;
  std::optional<std::vector<IndexedTopic>> indexed_;

  // Scan state.
  uint64_t next_record_ = 0;
  Record record_;
  HeaderFields inner_fields_;
  std::string header_buffer_;
  std::string compressed_;
  std::string chunk_;
  size_t chunk_pos_ = 0;
  uint64_t chunk_offset_ = 0;
  bool chunk_uncompressed_ = false;
  uint64_t chunk_data_offset_ = 0;
  std::string message_buffer_;
};

Ros1BagReader::Ros1BagReader(std::string path) : path_(std::move(path)) {
  fd_.Open(path_);
  if (fd_.get() < 0) throw Error("cannot open '" + path_ + "': " + std::strerror(errno));
  struct stat info;
  if (::fstat(fd_.get(), &info) != 0 || !S_ISREG(info.st_mode)) {
    throw Error("'" + path_ + "' is not a regular file");
  }
  file_bytes_ = static_cast<uint64_t>(info.st_size);
  ReadBagHeader();
  if (ReadIndex()) {
    records_end_ = index_pos_;
  } else {
    // Without an index the connections are only known from the chunks: scan once.
    records_end_ = index_pos_ != 0 ? index_pos_ : file_bytes_;
    indexed_.reset();
    connections_.clear();
    connection_index_.clear();
    Rewind();
    BagMessage ignored;
    while (Next(&ignored)) {
    }
  }
  Rewind();
}

void Ros1BagReader::Fail(uint64_t offset, const std::string& message) const {
  SourceLocation location;
  location.file = path_;
  location.byte_offset = static_cast<int64_t>(offset);
  throw ParseError(location, message);
}

void Ros1BagReader::ReadAt(uint64_t offset, size_t bytes, char* out, uint64_t record_offset,
                           const std::string& what) const {
  if (offset > file_bytes_ || bytes > file_bytes_ - offset) {
    Fail(record_offset, "truncated file: " + what + " needs bytes " + std::to_string(offset) +
                            " to " + std::to_string(offset + bytes) +
                            " but the file ends at byte " + std::to_string(file_bytes_));
  }
  size_t done = 0;
  while (done < bytes) {
    const ssize_t n =
        ::pread(fd_.get(), out + done, bytes - done, static_cast<off_t>(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      Fail(offset + done, std::string("read error: ") + (n < 0 ? std::strerror(errno) : "EOF"));
    }
    done += static_cast<size_t>(n);
  }
}

bool Ros1BagReader::ReadRecord(uint64_t offset, Record* record, bool cut_ok) {
  record->offset = offset;
  record->op = -1;
  record->end = file_bytes_;
  if (cut_ok && file_bytes_ - offset < 8) return false;
  char length[4];
  ReadAt(offset, 4, length, offset, "the record's header length");
  const uint32_t header_bytes = LoadU32(length);
  // With `cut_ok` the data length must fit too: the header cannot be read whole otherwise.
  if (header_bytes > file_bytes_ - std::min(file_bytes_, offset + (cut_ok ? 8 : 4))) {
    if (cut_ok) return false;
    Fail(offset, "truncated file: the record declares a header of " + std::to_string(header_bytes) +
                     " bytes but the file ends at byte " + std::to_string(file_bytes_));
  }
  header_buffer_.resize(header_bytes);
  ReadAt(offset + 4, header_bytes, header_buffer_.data(), offset,
         "the record's header of " + std::to_string(header_bytes) + " bytes");
  std::string why;
  if (!record->fields.Parse(header_buffer_, &why)) Fail(offset, "record header: " + why);
  const std::string_view* op = record->fields.Find("op");
  if (op == nullptr || op->size() != 1) Fail(offset, "record header has no one-byte 'op' field");
  record->op = static_cast<uint8_t>((*op)[0]);
  ReadAt(offset + 4 + header_bytes, 4, length, offset,
         "the " + OpName(record->op) + "'s data length");
  record->data_bytes = LoadU32(length);
  record->data_offset = offset + 8 + header_bytes;
  record->end = record->data_offset + record->data_bytes;
  if (record->end > file_bytes_) {
    if (cut_ok) return false;
    Fail(offset, "truncated file: the " + OpName(record->op) + " declares " +
                     std::to_string(record->data_bytes) + " bytes of data, ending at byte " +
                     std::to_string(record->end) + ", but the file ends at byte " +
                     std::to_string(file_bytes_));
  }
  return true;
}

template <typename T>
T Ros1BagReader::Field(const Record& record, const char* name) const {
  const std::string_view* value = record.fields.Find(name);
  if (value == nullptr || value->size() != sizeof(T)) {
    Fail(record.offset, "the " + OpName(record.op) + " has no " + std::to_string(sizeof(T)) +
                            "-byte field '" + name + "'");
  }
  T out;
  std::memcpy(&out, value->data(), sizeof(T));
  return out;
}

std::string Ros1BagReader::StringField(const HeaderFields& fields, uint64_t offset, int op,
                                       const char* name) const {
  const std::string_view* value = fields.Find(name);
  if (value == nullptr) Fail(offset, "the " + OpName(op) + " has no field '" + name + "'");
  return std::string(*value);
}

void Ros1BagReader::ReadBagHeader() {
  char magic[kMagicBytes];
  if (file_bytes_ < kMagicBytes) {
    Fail(0, "bad magic: not a ROS 1 bag (the file has " + std::to_string(file_bytes_) +
                " bytes, shorter than the line '#ROSBAG V2.0')");
  }
  ReadAt(0, kMagicBytes, magic, 0, "the magic line");
  if (std::memcmp(magic, kMagic, kMagicBytes) != 0) {
    const bool v12 = std::memcmp(magic, "#ROSBAG V1.2", 12) == 0;
    Fail(0, v12 ? "ROS bag format 1.2 is not supported (only 2.0): migrate it with "
                  "'rosbag fix' first"
                : "bad magic: not a ROS 1 bag (expected the line '#ROSBAG V2.0')");
  }
  ReadRecord(kMagicBytes, &record_);
  if (record_.op != kBagHeader) {
    Fail(kMagicBytes,
         "expected the bag header record (op 0x03), found op " + std::to_string(record_.op));
  }
  index_pos_ = Field<uint64_t>(record_, "index_pos");
  declared_connections_ = Field<uint32_t>(record_, "conn_count");
  declared_chunks_ = Field<uint32_t>(record_, "chunk_count");
  records_begin_ = record_.end;
  if (index_pos_ != 0 && (index_pos_ < records_begin_ || index_pos_ > file_bytes_)) {
    Fail(kMagicBytes, "truncated file: the bag header puts the index at byte " +
                          std::to_string(index_pos_) + " but the file ends at byte " +
                          std::to_string(file_bytes_));
  }
}

void Ros1BagReader::AddConnection(const HeaderFields& record_fields, std::string_view data,
                                  uint64_t offset, int op) {
  const std::string_view* conn = record_fields.Find("conn");
  if (conn == nullptr || conn->size() != 4) {
    Fail(offset, "the connection record has no 4-byte field 'conn'");
  }
  const uint32_t id = LoadU32(conn->data());
  if (connection_index_.count(id) != 0) return;
  HeaderFields data_fields;
  std::string why;
  if (!data_fields.Parse(data, &why)) Fail(offset, "connection record data: " + why);
  Connection connection;
  connection.id = id;
  connection.topic = StringField(record_fields, offset, op, "topic");
  connection.type = StringField(data_fields, offset, op, "type");
  connection.serialization = Serialization::kRos1;
  connection_index_[id] = connections_.size();
  connections_.push_back(std::move(connection));
}

// Reads connection and chunk info records at index_pos, then the index data records after
// each chunk. False when the index is missing or incomplete.
bool Ros1BagReader::ReadIndex() {
  if (index_pos_ == 0) return false;
  std::vector<uint64_t> chunk_positions;
  std::string data;
  for (uint64_t offset = index_pos_; offset < file_bytes_; offset = record_.end) {
    ReadRecord(offset, &record_);
    if (record_.op == kConnection) {
      data.resize(record_.data_bytes);
      ReadAt(record_.data_offset, data.size(), data.data(), offset, "the connection record's data");
      AddConnection(record_.fields, data, offset, record_.op);
    } else if (record_.op == kChunkInfo) {
      const uint64_t chunk_pos = Field<uint64_t>(record_, "chunk_pos");
      if (chunk_pos < records_begin_ || chunk_pos >= index_pos_) {
        Fail(offset, "the chunk info record points at byte " + std::to_string(chunk_pos) +
                         ", outside the bag's chunks (bytes " + std::to_string(records_begin_) +
                         " to " + std::to_string(index_pos_) + ")");
      }
      chunk_positions.push_back(chunk_pos);
    } else {
      Fail(offset, "unexpected " + OpName(record_.op) + " (op " + std::to_string(record_.op) +
                       ") after index_pos");
    }
  }
  if (chunk_positions.size() != declared_chunks_ || connections_.size() != declared_connections_) {
    // Incomplete: the chunks are scanned instead.
    return false;
  }
  ReadChunkIndexes(chunk_positions);
  return true;
}

// The index data records that follow each chunk: per connection, message count and the
// first and last record times.
void Ros1BagReader::ReadChunkIndexes(const std::vector<uint64_t>& chunk_positions) {
  std::map<uint32_t, IndexedTopic> topics;
  std::string data;
  for (const uint64_t chunk_pos : chunk_positions) {
    ReadRecord(chunk_pos, &record_);
    if (record_.op != kChunk) {
      Fail(chunk_pos, "a chunk info record points here, but this is a " + OpName(record_.op));
    }
    for (uint64_t offset = record_.end; offset < index_pos_;) {
      ReadRecord(offset, &record_);
      if (record_.op != kIndexData) break;
      const uint32_t conn = Field<uint32_t>(record_, "conn");
      const uint32_t count = Field<uint32_t>(record_, "count");
      if (Field<uint32_t>(record_, "ver") != 1) Fail(offset, "index data record version is not 1");
      if (uint64_t{count} * 12 != record_.data_bytes) {
        Fail(offset, "the index data record declares " + std::to_string(count) +
                         " entries (12 bytes each) but holds " +
                         std::to_string(record_.data_bytes) + " bytes");
      }
      if (connection_index_.count(conn) == 0) {
        Fail(offset, "the index data record names connection " + std::to_string(conn) +
                         ", which the index does not define");
      }
      data.resize(record_.data_bytes);
      ReadAt(record_.data_offset, data.size(), data.data(), offset, "the index entries");
      IndexedTopic& topic = topics[conn];
      for (uint32_t i = 0; i < count; ++i) {
        const std::optional<int64_t> time_ns = LoadTimeNs(data.data() + 12 * i);
        if (!time_ns) Fail(offset, "index entry " + std::to_string(i) + ": " + kBadTime);
        const int64_t t_ns = *time_ns;
        if (topic.message_count == 0 || t_ns < topic.first_log_time_ns)
          topic.first_log_time_ns = t_ns;
        if (topic.message_count == 0 || t_ns > topic.last_log_time_ns)
          topic.last_log_time_ns = t_ns;
        ++topic.message_count;
      }
      offset = record_.end;
    }
  }
  std::vector<IndexedTopic> list;
  for (const Connection& connection : connections_) {
    IndexedTopic topic = topics[connection.id];
    topic.connection_id = connection.id;
    list.push_back(topic);
  }
  indexed_ = std::move(list);
}

void Ros1BagReader::Rewind() {
  next_record_ = records_begin_;
  warnings_.clear();
  chunk_.clear();
  chunk_pos_ = 0;
}

void Ros1BagReader::LoadChunk(const Record& record) {
  const std::string compression =
      StringField(record.fields, record.offset, record.op, "compression");
  const uint32_t size = Field<uint32_t>(record, "size");
  if (size > kMaxChunkBytes) {
    Fail(record.offset, "the chunk declares " + std::to_string(size) +
                            " bytes uncompressed, more than the 1 GiB limit");
  }
  chunk_offset_ = record.offset;
  chunk_data_offset_ = record.data_offset;
  chunk_pos_ = 0;
  chunk_uncompressed_ = compression == "none";
  if (chunk_uncompressed_) {
    if (size != record.data_bytes) {
      Fail(record.offset, "the uncompressed chunk declares size " + std::to_string(size) +
                              " but holds " + std::to_string(record.data_bytes) + " bytes");
    }
    chunk_.resize(size);
    ReadAt(record.data_offset, size, chunk_.data(), record.offset, "the chunk's data");
    return;
  }
  if (compression != "bz2" && compression != "lz4") {
    Fail(record.offset,
         "unknown chunk compression '" + compression + "' (expected none, bz2 or lz4)");
  }
  // LZ4 cannot expand data more than 255-fold; a larger declared size is a lie, refused
  // before anything is allocated for it.
  if (compression == "lz4" && size > 255 * uint64_t{record.data_bytes} + 64) {
    Fail(record.offset, "chunk record: the lz4 chunk of " + std::to_string(record.data_bytes) +
                            " bytes declares " + std::to_string(size) +
                            " bytes uncompressed, more than lz4 can expand to");
  }
  // Neither stream grows incompressible data by more than a few parts in a thousand plus its
  // framing (bz2 about 1 %, lz4 0.4 %): compressed data far beyond the declared size is a lie,
  // refused before it is read.
  if (record.data_bytes > size + size / 8 + 65536) {
    Fail(record.offset, "chunk record: the " + compression + " chunk's " +
                            std::to_string(record.data_bytes) +
                            " compressed bytes are far more than the " + std::to_string(size) +
                            " bytes it declares uncompressed");
  }
  compressed_.resize(record.data_bytes);
  ReadAt(record.data_offset, record.data_bytes, compressed_.data(), record.offset,
         "the chunk's data");
  const std::string why = compression == "bz2"
                              ? DecompressBz2Chunk(compressed_, size, &chunk_)
                              : DecompressLz4FrameChunk(compressed_, size, &chunk_);
  if (!why.empty()) Fail(record.offset, "chunk record: " + why);
}

bool Ros1BagReader::NextInChunk(BagMessage* message) {
  while (chunk_pos_ < chunk_.size()) {
    const size_t start = chunk_pos_;
    const auto fail = [&](const std::string& what) {
      Fail(chunk_offset_, "chunk record: the record at byte " + std::to_string(start) +
                              " of the uncompressed chunk (" + std::to_string(chunk_.size()) +
                              " bytes): " + what);
    };
    if (chunk_.size() - start < 4) fail("header length cut off at the chunk's end");
    const uint32_t header_bytes = LoadU32(chunk_.data() + start);
    if (header_bytes > chunk_.size() - start - 4 || chunk_.size() - start - 4 - header_bytes < 4) {
      fail("its header of " + std::to_string(header_bytes) + " bytes runs past the chunk's end");
    }
    const std::string_view header(chunk_.data() + start + 4, header_bytes);
    const size_t data_start = start + 8 + header_bytes;
    const uint32_t data_bytes = LoadU32(chunk_.data() + data_start - 4);
    if (data_bytes > chunk_.size() - data_start) {
      fail("its data of " + std::to_string(data_bytes) + " bytes runs past the chunk's end");
    }
    std::string why;
    if (!inner_fields_.Parse(header, &why)) fail(why);
    chunk_pos_ = data_start + data_bytes;
    const std::string_view* op = inner_fields_.Find("op");
    if (op == nullptr || op->size() != 1) fail("header has no one-byte 'op' field");
    const std::string_view data(chunk_.data() + data_start, data_bytes);
    const uint64_t file_offset = chunk_uncompressed_ ? chunk_data_offset_ + start : chunk_offset_;
    if ((*op)[0] == kConnection) {
      AddConnection(inner_fields_, data, file_offset, kConnection);
    } else if ((*op)[0] == kMessageData) {
      const std::string_view* conn = inner_fields_.Find("conn");
      const std::string_view* time = inner_fields_.Find("time");
      if (conn == nullptr || conn->size() != 4 || time == nullptr || time->size() != 8) {
        fail("message data record without a 4-byte 'conn' and an 8-byte 'time'");
      }
      message->connection_id = LoadU32(conn->data());
      if (connection_index_.count(message->connection_id) == 0) {
        fail("message data record on connection " + std::to_string(message->connection_id) +
             ", which no connection record defines");
      }
      const std::optional<int64_t> log_time_ns = LoadTimeNs(time->data());
      if (!log_time_ns) fail("message data record: 'time' " + std::string(kBadTime));
      message->log_time_ns = *log_time_ns;
      message->data = data;
      message->file_offset = file_offset;
      return true;
    } else {
      fail("unexpected op " + std::to_string(static_cast<uint8_t>((*op)[0])) + " inside a chunk");
    }
  }
  return false;
}

bool Ros1BagReader::IsOpenChunk(const Record& record) const {
  return record.op == kChunk && record.data_bytes == 0 && Field<uint32_t>(record, "size") == 0;
}

void Ros1BagReader::LoadOpenChunk(const Record& record) {
  const uint64_t data_bytes = file_bytes_ - record.data_offset;
  if (data_bytes > kMaxChunkBytes) {
    Fail(record.offset, "the chunk left open holds " + std::to_string(data_bytes) +
                            " bytes, more than the 1 GiB limit");
  }
  const std::string compression =
      StringField(record.fields, record.offset, record.op, "compression");
  chunk_offset_ = record.offset;
  chunk_data_offset_ = record.data_offset;
  chunk_pos_ = 0;
  chunk_uncompressed_ = compression == "none";
  std::string note;
  if (chunk_uncompressed_) {
    chunk_.resize(data_bytes);
    ReadAt(record.data_offset, data_bytes, chunk_.data(), record.offset, "the chunk's data");
  } else if (compression == "bz2" || compression == "lz4") {
    compressed_.resize(data_bytes);
    ReadAt(record.data_offset, data_bytes, compressed_.data(), record.offset, "the chunk's data");
    bool ended = false;
    const std::string why =
        compression == "bz2"
            ? DecompressCutBz2Chunk(compressed_, kMaxChunkBytes, &chunk_, &ended)
            : DecompressCutLz4FrameChunk(compressed_, kMaxChunkBytes, &chunk_, &ended);
    if (!why.empty()) Fail(record.offset, "chunk record left open: " + why);
    if (!ended) {
      note = "; its " + compression +
             " stream is cut short: what follows its last whole block "
             "was left";
    }
  } else {
    Fail(record.offset,
         "unknown chunk compression '" + compression + "' (expected none, bz2 or lz4)");
  }
  // Whole records only: the last one may be cut by the file's end.
  size_t whole = 0;
  size_t messages = 0;
  for (;;) {
    const size_t left = chunk_.size() - whole;
    if (left < 8) break;
    const uint32_t header_bytes = LoadU32(chunk_.data() + whole);
    if (header_bytes > left - 8) break;
    const uint32_t data_bytes_of_record = LoadU32(chunk_.data() + whole + 4 + header_bytes);
    if (data_bytes_of_record > left - 8 - header_bytes) break;
    std::string why;
    if (inner_fields_.Parse(std::string_view(chunk_.data() + whole + 4, header_bytes), &why)) {
      const std::string_view* op = inner_fields_.Find("op");
      if (op != nullptr && op->size() == 1 && (*op)[0] == kMessageData) ++messages;
    }
    whole += 8 + size_t{header_bytes} + data_bytes_of_record;
  }
  if (chunk_.size() > whole) {
    note += "; a record cut short (" + std::to_string(chunk_.size() - whole) + " bytes) was left";
  }
  warnings_.push_back(path_ + ": byte " + std::to_string(record.offset) + ": " +
                      (record.data_bytes == 0
                           ? "the last chunk was left open (the recorder stopped before "
                             "closing the bag)"
                           : "the last chunk is cut short by the file's end") +
                      ": " + std::to_string(messages) + " messages read from it" + note);
  chunk_.resize(whole);
}

bool Ros1BagReader::Next(BagMessage* message) {
  for (;;) {
    if (NextInChunk(message)) return true;
    if (next_record_ >= records_end_) return false;
    // index_pos 0: the recorder never closed the bag, its last records may be cut short.
    const bool recorder_stopped = index_pos_ == 0;
    if (!ReadRecord(next_record_, &record_, recorder_stopped) ||
        (recorder_stopped && IsOpenChunk(record_))) {
      next_record_ = file_bytes_;
      if (record_.op == kChunk) {
        LoadOpenChunk(record_);
      } else {
        warnings_.push_back(path_ + ": byte " + std::to_string(record_.offset) +
                            ": the last record is cut short by the file's end; its " +
                            std::to_string(file_bytes_ - record_.offset) +
                            " bytes were left (the recorder stopped before closing the bag)");
      }
      continue;
    }
    next_record_ = record_.end;
    switch (record_.op) {
      case kChunk:
        LoadChunk(record_);
        break;
      case kConnection:
        message_buffer_.resize(record_.data_bytes);
        ReadAt(record_.data_offset, record_.data_bytes, message_buffer_.data(), record_.offset,
               "the connection record's data");
        AddConnection(record_.fields, message_buffer_, record_.offset, kConnection);
        break;
      case kIndexData:
      case kChunkInfo:
        break;  // the index, read up front
      default:
        Fail(record_.offset, "unexpected " + OpName(record_.op) + " (op " +
                                 std::to_string(record_.op) + ") among the chunks");
    }
  }
}

}  // namespace
}  // namespace ros1

std::unique_ptr<BagReader> OpenRos1Bag(const std::string& path) {
  return std::make_unique<ros1::Ros1BagReader>(path);
}

}  // namespace import
}  // namespace autocal
