#pragma once

// A small MCAP writer for the reader's tests and benchmark: files with or without chunks,
// chunk compression "", "lz4" or "zstd", message indexes, a summary section (schemas,
// channels, statistics, chunk indexes, summary offsets) and the CRCs, each switchable so
// every path of the reader is exercised. It follows mcap.dev/spec; it checks nothing of
// what it is given (tests write malformed files with it on purpose).

#include <lz4frame.h>
#include <zstd.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "import/crc32.h"

namespace autocal {
namespace test {

struct McapWriterOptions {
  bool chunked = true;
  std::string compression;    // "", "lz4" or "zstd"
  size_t chunk_bytes = 1024;  // a chunk is closed once its records reach this size
  bool chunk_crc = true;
  bool message_indexes = true;
  bool summary = true;  // schemas, channels, statistics and chunk indexes after Data End
  bool statistics = true;
  bool summary_offsets = true;
  bool summary_crc = true;
  bool data_crc = false;
  bool data_end = true;
};

class McapWriter {
 public:
  explicit McapWriter(McapWriterOptions options = {}) : options_(std::move(options)) {
    out_.append("\x89MCAP0\r\n", 8);
    std::string header;
    PutString(&header, "ros2");
    PutString(&header, "autocal test writer");
    PutRecord(&out_, 0x01, header);
  }

  // Writes a Schema record (in the current chunk when chunked) and returns its id.
  uint16_t AddSchema(const std::string& name, const std::string& encoding = "ros2msg",
                     const std::string& text = "string data\n") {
    const uint16_t id = static_cast<uint16_t>(schemas_.size() + 1);
    std::string content;
    Put<uint16_t>(&content, id);
    PutString(&content, name);
    PutString(&content, encoding);
    PutString(&content, text);
    schemas_.push_back(content);
    PutRecord(Stream(), 0x03, content);
    return id;
  }

  // Writes a Channel record and returns its id (1, 2, ...).
  uint16_t AddChannel(uint16_t schema_id, const std::string& topic,
                      const std::string& message_encoding = "cdr") {
    const uint16_t id = static_cast<uint16_t>(channels_.size() + 1);
    std::string content;
    Put<uint16_t>(&content, id);
    Put<uint16_t>(&content, schema_id);
    PutString(&content, topic);
    PutString(&content, message_encoding);
    std::string metadata;
    PutString(&metadata, "offered_qos_profiles");
    PutString(&metadata, "");
    PutString(&content, metadata);
    channels_.push_back(content);
    PutRecord(Stream(), 0x04, content);
    return id;
  }

  void AddMessage(uint16_t channel_id, uint64_t log_time_ns, std::string_view data) {
    std::string content;
    Put<uint16_t>(&content, channel_id);
    Put<uint32_t>(&content, sequence_++);
    Put<uint64_t>(&content, log_time_ns);
    Put<uint64_t>(&content, log_time_ns);
    content.append(data);
    if (options_.chunked) {
      chunk_index_[channel_id].push_back({log_time_ns, chunk_.size()});
      chunk_start_ns_ = chunk_messages_ == 0 ? log_time_ns : std::min(chunk_start_ns_, log_time_ns);
      chunk_end_ns_ = chunk_messages_ == 0 ? log_time_ns : std::max(chunk_end_ns_, log_time_ns);
      ++chunk_messages_;
    }
    PutRecord(Stream(), 0x05, content);
    ++channel_counts_[channel_id];
    start_ns_ = message_count_ == 0 ? log_time_ns : std::min(start_ns_, log_time_ns);
    end_ns_ = message_count_ == 0 ? log_time_ns : std::max(end_ns_, log_time_ns);
    ++message_count_;
    if (options_.chunked && chunk_.size() >= options_.chunk_bytes) FlushChunk();
  }

  // An attachment and a metadata record in the data section (outside chunks).
  void AddAttachmentAndMetadata() {
    FlushChunk();
    std::string attachment;
    Put<uint64_t>(&attachment, 1);
    Put<uint64_t>(&attachment, 2);
    PutString(&attachment, "calibration.yaml");
    PutString(&attachment, "text/yaml");
    Put<uint64_t>(&attachment, 5);
    attachment.append("a: 1\n");
    Put<uint32_t>(&attachment, import::Crc32(attachment));
    PutRecord(&out_, 0x09, attachment);
    std::string metadata;
    PutString(&metadata, "run");
    std::string map;
    PutString(&map, "vehicle");
    PutString(&map, "test");
    PutString(&metadata, map);
    PutRecord(&out_, 0x0C, metadata);
  }

  // The file: Data End, the summary, the footer and the magic.
  std::string Finish() {
    FlushChunk();
    if (options_.data_end) {
      std::string data_end;
      Put<uint32_t>(&data_end, options_.data_crc ? import::Crc32(out_) : 0);
      PutRecord(&out_, 0x0F, data_end);
    }
    uint64_t summary_start = 0;
    uint64_t summary_offset_start = 0;
    if (options_.summary) {
      summary_start = out_.size();
      WriteSummary();
      summary_offset_start = options_.summary_offsets ? out_.size() : 0;
      for (const auto& [opcode, group] : groups_) {
        if (!options_.summary_offsets) break;
        std::string offset;
        offset.push_back(static_cast<char>(opcode));
        Put<uint64_t>(&offset, group.first);
        Put<uint64_t>(&offset, group.second);
        PutRecord(&out_, 0x0E, offset);
      }
    }
    footer_offset_ = out_.size();
    std::string footer;
    Put<uint64_t>(&footer, summary_start);
    Put<uint64_t>(&footer, summary_offset_start);
    out_.push_back(0x02);
    Put<uint64_t>(&out_, 20);
    out_ += footer;
    const uint32_t crc = options_.summary && options_.summary_crc
                             ? import::Crc32(std::string_view(out_).substr(
                                   summary_start, out_.size() - summary_start))
                             : 0;
    Put<uint32_t>(&out_, crc);
    out_.append("\x89MCAP0\r\n", 8);
    return out_;
  }

  // File offsets of the Chunk records written so far.
  const std::vector<uint64_t>& chunk_offsets() const { return chunk_offsets_; }
  uint64_t footer_offset() const { return footer_offset_; }

  template <typename T>
  static void Put(std::string* out, T value) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    out->append(bytes, sizeof(T));
  }
  static void PutString(std::string* out, std::string_view text) {
    Put<uint32_t>(out, static_cast<uint32_t>(text.size()));
    out->append(text);
  }
  static void PutRecord(std::string* out, uint8_t opcode, std::string_view content) {
    out->push_back(static_cast<char>(opcode));
    Put<uint64_t>(out, content.size());
    out->append(content);
  }

 private:
  struct ChunkIndexEntry {
    uint64_t start_ns, end_ns, offset, length, index_length, compressed_size, uncompressed_size;
    std::map<uint16_t, uint64_t> index_offsets;
  };

  std::string* Stream() { return options_.chunked ? &chunk_ : &out_; }

  std::string Compress(const std::string& records) const {
    if (options_.compression == "zstd") {
      std::string out(ZSTD_compressBound(records.size()), '\0');
      const size_t n = ZSTD_compress(out.data(), out.size(), records.data(), records.size(), 3);
      if (ZSTD_isError(n)) throw std::runtime_error("zstd compression failed");
      out.resize(n);
      return out;
    }
    if (options_.compression == "lz4") {
      std::string out(LZ4F_compressFrameBound(records.size(), nullptr), '\0');
      const size_t n =
          LZ4F_compressFrame(out.data(), out.size(), records.data(), records.size(), nullptr);
      if (LZ4F_isError(n)) throw std::runtime_error("lz4 compression failed");
      out.resize(n);
      return out;
    }
    return records;  // "" or a name the reader must refuse
  }

  void FlushChunk() {
    if (!options_.chunked || chunk_.empty()) return;
    const std::string compressed = Compress(chunk_);
    std::string content;
    Put<uint64_t>(&content, chunk_messages_ ? chunk_start_ns_ : 0);
    Put<uint64_t>(&content, chunk_messages_ ? chunk_end_ns_ : 0);
    Put<uint64_t>(&content, chunk_.size());
    Put<uint32_t>(&content, options_.chunk_crc ? import::Crc32(chunk_) : 0);
    PutString(&content, options_.compression);
    Put<uint64_t>(&content, compressed.size());
    content += compressed;
    ChunkIndexEntry entry{chunk_messages_ ? chunk_start_ns_ : 0,
                          chunk_messages_ ? chunk_end_ns_ : 0,
                          out_.size(),
                          9 + content.size(),
                          0,
                          compressed.size(),
                          chunk_.size(),
                          {}};
    chunk_offsets_.push_back(out_.size());
    PutRecord(&out_, 0x06, content);
    const uint64_t index_start = out_.size();
    for (const auto& [channel_id, entries] : chunk_index_) {
      if (!options_.message_indexes) break;
      std::string index;
      Put<uint16_t>(&index, channel_id);
      Put<uint32_t>(&index, static_cast<uint32_t>(entries.size() * 16));
      for (const auto& [time_ns, offset] : entries) {
        Put<uint64_t>(&index, time_ns);
        Put<uint64_t>(&index, offset);
      }
      entry.index_offsets[channel_id] = out_.size();
      PutRecord(&out_, 0x07, index);
    }
    entry.index_length = out_.size() - index_start;
    chunk_indexes_.push_back(entry);
    chunk_.clear();
    chunk_index_.clear();
    chunk_messages_ = 0;
  }

  void WriteSummary() {
    Group(0x03, [&] {
      for (const std::string& schema : schemas_) PutRecord(&out_, 0x03, schema);
    });
    Group(0x04, [&] {
      for (const std::string& channel : channels_) PutRecord(&out_, 0x04, channel);
    });
    if (options_.statistics) {
      Group(0x0B, [&] {
        std::string statistics;
        Put<uint64_t>(&statistics, message_count_);
        Put<uint16_t>(&statistics, static_cast<uint16_t>(schemas_.size()));
        Put<uint32_t>(&statistics, static_cast<uint32_t>(channels_.size()));
        Put<uint32_t>(&statistics, 0);
        Put<uint32_t>(&statistics, 0);
        Put<uint32_t>(&statistics, static_cast<uint32_t>(chunk_indexes_.size()));
        Put<uint64_t>(&statistics, start_ns_);
        Put<uint64_t>(&statistics, end_ns_);
        std::string counts;
        for (const auto& [channel_id, count] : channel_counts_) {
          Put<uint16_t>(&counts, channel_id);
          Put<uint64_t>(&counts, count);
        }
        PutString(&statistics, counts);
        PutRecord(&out_, 0x0B, statistics);
      });
    }
    Group(0x08, [&] {
      for (const ChunkIndexEntry& entry : chunk_indexes_) {
        std::string index;
        Put<uint64_t>(&index, entry.start_ns);
        Put<uint64_t>(&index, entry.end_ns);
        Put<uint64_t>(&index, entry.offset);
        Put<uint64_t>(&index, entry.length);
        std::string offsets;
        for (const auto& [channel_id, offset] : entry.index_offsets) {
          Put<uint16_t>(&offsets, channel_id);
          Put<uint64_t>(&offsets, offset);
        }
        PutString(&index, offsets);
        Put<uint64_t>(&index, entry.index_length);
        PutString(&index, options_.compression);
        Put<uint64_t>(&index, entry.compressed_size);
        Put<uint64_t>(&index, entry.uncompressed_size);
        PutRecord(&out_, 0x08, index);
      }
    });
  }

  template <typename WriteGroup>
  void Group(uint8_t opcode, WriteGroup write) {
    const uint64_t start = out_.size();
    write();
    if (out_.size() > start) groups_[opcode] = {start, out_.size() - start};
  }

  McapWriterOptions options_;
  std::string out_;
  std::string chunk_;
  std::vector<std::string> schemas_;
  std::vector<std::string> channels_;
  uint32_t sequence_ = 0;
  uint64_t message_count_ = 0;
  uint64_t start_ns_ = 0;
  uint64_t end_ns_ = 0;
  std::map<uint16_t, uint64_t> channel_counts_;
  std::map<uint16_t, std::vector<std::pair<uint64_t, uint64_t>>> chunk_index_;
  uint64_t chunk_messages_ = 0;
  uint64_t chunk_start_ns_ = 0;
  uint64_t chunk_end_ns_ = 0;
  std::vector<ChunkIndexEntry> chunk_indexes_;
  std::vector<uint64_t> chunk_offsets_;
  std::map<uint8_t, std::pair<uint64_t, uint64_t>> groups_;
  uint64_t footer_offset_ = 0;
};

// A std_msgs/msg/String as ROS 2 serializes it: the CDR little-endian encapsulation header,
// the length including the terminating NUL, the bytes and the NUL.
inline std::string CdrString(std::string_view text) {
  std::string out("\x00\x01\x00\x00", 4);
  McapWriter::Put<uint32_t>(&out, static_cast<uint32_t>(text.size() + 1));
  out.append(text);
  out.push_back('\0');
  return out;
}

inline void WriteFile(const std::string& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path);
}

}  // namespace test
}  // namespace autocal
