#pragma once

// Walks the records of an MCAP data section in file order, opening chunks on the way:
// Schema, Channel and Message records come out whether they lie in a chunk or not. Chunks
// are decompressed one at a time into a reused buffer (memory bounded by the largest chunk)
// and checked: declared sizes, compression, and the CRC-32 of the records when non-zero.
// The data section's own CRC (Data End) is checked when the file gives one.

#include <cstdint>
#include <string>
#include <string_view>

#include "import/mcap_decompress.h"
#include "import/mcap_format.h"

namespace autocal {
namespace import {
namespace internal {

struct McapRecord {
  uint8_t opcode = 0;
  std::string_view content;
  // Where the content starts: in the file, or in the chunk's records when in_chunk.
  uint64_t content_offset = 0;
  // The file offset of the top-level record holding it (the record itself or its chunk).
  uint64_t file_offset = 0;
  bool in_chunk = false;
};

class McapDataWalker {
 public:
  // `file` is the whole file, the data section's records lie in [begin, end). When
  // `data_section_crc` is non-zero, it is checked at Data End against the CRC-32 of all
  // bytes before that record.
  McapDataWalker(const std::string& path, std::string_view file, uint64_t begin, uint64_t end,
                 uint32_t data_section_crc);

  // The next record; false after Data End or at `end`. Throws ParseError on a malformed
  // record (its length past the end, a chunk that does not decompress to its size, ...).
  bool Next(McapRecord* record);

  // The place of the record returned last, for the caller's own errors.
  const McapPlace& place() const { return in_chunk_ ? chunk_place_ : file_place_; }

 private:
  bool NextInChunk(McapRecord* record);
  void OpenChunk(std::string_view content, uint64_t record_offset);
  void CheckDataEnd(std::string_view content, uint64_t record_offset);

  const std::string& path_;
  std::string_view file_;
  uint64_t pos_;
  uint64_t end_;
  bool done_ = false;
  uint32_t expected_data_crc_;
  uint32_t data_crc_ = 0;

  McapPlace file_place_;
  McapPlace chunk_place_;
  bool in_chunk_ = false;
  std::string_view chunk_records_;
  uint64_t chunk_pos_ = 0;
  uint64_t chunk_file_offset_ = 0;
  Decompressor decompressor_;
  ByteBuffer chunk_buffer_;
};

}  // namespace internal
}  // namespace import
}  // namespace autocal
