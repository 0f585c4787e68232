#include "import/mcap_data_walker.h"

#include "import/crc32.h"

namespace autocal {
namespace import {
namespace internal {
namespace {

// Larger declared chunks are refused before any allocation (no recorder writes them; the
// default chunk is a few MB).
constexpr uint64_t kMaxChunkBytes = uint64_t{1} << 30;

uint64_t ReadU64(const char* bytes) {
  uint64_t value;
  std::memcpy(&value, bytes, sizeof(value));
  return value;
}

}  // namespace

McapDataWalker::McapDataWalker(const std::string& path, std::string_view file, uint64_t begin,
                               uint64_t end, uint32_t data_section_crc)
    : path_(path), file_(file), pos_(begin), end_(end), expected_data_crc_(data_section_crc) {
  file_place_.path = &path_;
  chunk_place_.path = &path_;
  if (expected_data_crc_ != 0) data_crc_ = Crc32Update(0, file_.data(), begin);
}

bool McapDataWalker::Next(McapRecord* record) {
  while (true) {
    if (in_chunk_) {
      if (NextInChunk(record)) return true;
      in_chunk_ = false;
    }
    if (done_) return false;
    if (pos_ == end_) {
      // The spec's last record of the data section: without it a record whose length ran
      // over the records after it would end the messages early without a word.
      file_place_.Fail(pos_, kOpDataEnd,
                       "missing: the data section ends here without one (a record length that "
                       "does not match its record?)");
    }
    const uint64_t offset = pos_;
    if (end_ - pos_ < kMcapRecordPrefixBytes) {
      file_place_.Fail(offset, static_cast<uint8_t>(file_[offset]),
                       "the record's opcode and length need 9 bytes, the data section has " +
                           std::to_string(end_ - pos_) + " left (truncated file)");
    }
    const uint8_t opcode = static_cast<uint8_t>(file_[offset]);
    const uint64_t length = ReadU64(file_.data() + offset + 1);
    const uint64_t left = end_ - pos_ - kMcapRecordPrefixBytes;
    if (length > left) {
      file_place_.Fail(offset, opcode,
                       "its length " + std::to_string(length) +
                           " runs past the end of the data section (" + std::to_string(left) +
                           " bytes left; truncated file?)");
    }
    const std::string_view content = file_.substr(offset + kMcapRecordPrefixBytes, length);
    pos_ += kMcapRecordPrefixBytes + length;
    if (opcode == kOpDataEnd) {
      CheckDataEnd(content, offset);
      done_ = true;
      return false;
    }
    if (expected_data_crc_ != 0) {
      data_crc_ = Crc32Update(data_crc_, file_.data() + offset, kMcapRecordPrefixBytes + length);
    }
    if (opcode == kOpChunk) {
      OpenChunk(content, offset);
      continue;
    }
    if (opcode == kOpHeader || opcode == kOpFooter) {
      file_place_.Fail(offset, opcode, "a second header or a footer inside the data section");
    }
    *record = McapRecord{opcode, content, offset + kMcapRecordPrefixBytes, offset, false};
    return true;
  }
}

bool McapDataWalker::NextInChunk(McapRecord* record) {
  if (chunk_pos_ == chunk_records_.size()) return false;
  const uint64_t offset = chunk_pos_;
  const uint64_t available = chunk_records_.size() - chunk_pos_;
  if (available < kMcapRecordPrefixBytes) {
    chunk_place_.Fail(offset, static_cast<uint8_t>(chunk_records_[offset]),
                      "the record's opcode and length need 9 bytes, the chunk has " +
                          std::to_string(available) + " left");
  }
  const uint8_t opcode = static_cast<uint8_t>(chunk_records_[offset]);
  const uint64_t length = ReadU64(chunk_records_.data() + offset + 1);
  if (length > available - kMcapRecordPrefixBytes) {
    chunk_place_.Fail(offset, opcode,
                      "its length " + std::to_string(length) + " runs past the end of the chunk (" +
                          std::to_string(available - kMcapRecordPrefixBytes) + " bytes left)");
  }
  chunk_pos_ += kMcapRecordPrefixBytes + length;
  *record = McapRecord{opcode, chunk_records_.substr(offset + kMcapRecordPrefixBytes, length),
                       offset + kMcapRecordPrefixBytes, chunk_file_offset_, true};
  return true;
}

void McapDataWalker::OpenChunk(std::string_view content, uint64_t record_offset) {
  McapFields fields(content, record_offset + kMcapRecordPrefixBytes, kOpChunk, file_place_);
  fields.Time("message_start_time");
  fields.Time("message_end_time");
  const uint64_t uncompressed_size = fields.U64("uncompressed_size");
  const uint32_t uncompressed_crc = fields.U32("uncompressed_crc");
  const std::string_view compression = fields.Prefixed32("compression");
  const std::string_view records = fields.Prefixed64("records");
  const auto fail = [&](const std::string& message) {
    file_place_.Fail(record_offset, kOpChunk, message);
  };

  if (compression.empty()) {
    if (uncompressed_size != records.size()) {
      fail("uncompressed_size " + std::to_string(uncompressed_size) + " differs from the " +
           std::to_string(records.size()) + " bytes of its uncompressed records");
    }
    chunk_records_ = records;
  } else if (Decompressor::Supports(compression)) {
    if (uncompressed_size > kMaxChunkBytes) {
      fail("uncompressed_size " + std::to_string(uncompressed_size) +
           " is beyond the 1 GiB this reader accepts");
    }
    char* out = chunk_buffer_.Reserve(uncompressed_size);
    const std::string error =
        decompressor_.Decompress(compression, records, out, uncompressed_size);
    if (!error.empty()) fail(error);
    chunk_records_ = std::string_view(out, uncompressed_size);
  } else {
    fail("unknown compression '" + std::string(compression) +
         "' (supported: none, \"zstd\", \"lz4\")");
  }
  if (uncompressed_crc != 0) {
    const uint32_t crc = Crc32(chunk_records_);
    if (crc != uncompressed_crc) {
      fail("the CRC-32 of its uncompressed records is " + Hex(crc) + ", the chunk says " +
           Hex(uncompressed_crc) + " (corrupt data)");
    }
  }
  chunk_pos_ = 0;
  chunk_file_offset_ = record_offset;
  chunk_place_.chunk_offset = static_cast<int64_t>(record_offset);
  in_chunk_ = true;
}

void McapDataWalker::CheckDataEnd(std::string_view content, uint64_t record_offset) {
  McapFields fields(content, record_offset + kMcapRecordPrefixBytes, kOpDataEnd, file_place_);
  const uint32_t crc = fields.U32("data_section_crc");
  if (crc != 0 && expected_data_crc_ != 0 && crc != data_crc_) {
    file_place_.Fail(record_offset, kOpDataEnd,
                     "the CRC-32 of the data section is " + Hex(data_crc_) + ", the record says " +
                         Hex(crc) + " (corrupt data)");
  }
}

}  // namespace internal
}  // namespace import
}  // namespace autocal
