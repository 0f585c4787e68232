#pragma once

// The MCAP container's record layout (mcap.dev/spec, major version 0): opcodes, the magic,
// and a bounds-checked reader of a record's little-endian fields whose every failure is one
// ParseError naming the file, the byte offset and the record kind.

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace autocal {
namespace import {
namespace internal {

inline constexpr std::string_view kMcapMagic("\x89MCAP0\r\n", 8);
inline constexpr uint64_t kMcapRecordPrefixBytes = 9;  // opcode + uint64 content length
inline constexpr uint64_t kMcapFooterContentBytes = 20;

enum McapOpcode : uint8_t {
  kOpHeader = 0x01,
  kOpFooter = 0x02,
  kOpSchema = 0x03,
  kOpChannel = 0x04,
  kOpMessage = 0x05,
  kOpChunk = 0x06,
  kOpMessageIndex = 0x07,
  kOpChunkIndex = 0x08,
  kOpAttachment = 0x09,
  kOpAttachmentIndex = 0x0A,
  kOpStatistics = 0x0B,
  kOpMetadata = 0x0C,
  kOpMetadataIndex = 0x0D,
  kOpSummaryOffset = 0x0E,
  kOpDataEnd = 0x0F,
};

// "0x1A2B3C4D", for CRCs in messages.
std::string Hex(uint32_t value);

// "Chunk", "Message", ... or "unknown (0x42)".
std::string McapRecordName(uint8_t opcode);

// Where a record lies, for error messages: a byte offset in the file, or an offset in the
// decompressed records of the chunk at `chunk_offset`.
struct McapPlace {
  const std::string* path = nullptr;
  int64_t chunk_offset = -1;  // -1: the offset is in the file itself

  // Throws the ParseError "<path>: byte N: <kind> record[ at byte K of the chunk's
  // uncompressed records]: <message>".
  [[noreturn]] void Fail(uint64_t offset, uint8_t opcode, const std::string& message) const;
};

// Reads the fields of one record's content in order. `offset` is where the content starts
// (in the file or in the chunk, as `place` says).
class McapFields {
 public:
  McapFields(std::string_view content, uint64_t offset, uint8_t opcode, const McapPlace& place)
      : content_(content), offset_(offset), opcode_(opcode), place_(place) {}

  uint8_t U8(const char* field) { return Fixed<uint8_t>(field); }
  uint16_t U16(const char* field) { return Fixed<uint16_t>(field); }
  uint32_t U32(const char* field) { return Fixed<uint32_t>(field); }
  uint64_t U64(const char* field) { return Fixed<uint64_t>(field); }
  // A Timestamp (uint64 ns); one beyond int64 is refused.
  int64_t Time(const char* field);
  // A uint32-length-prefixed String, Bytes, Array or Map (the bytes, unparsed).
  std::string_view Prefixed32(const char* field) { return Take(U32(field), field); }
  std::string_view Prefixed64(const char* field) { return Take(U64(field), field); }
  // The remaining bytes (a Message's data).
  std::string_view Rest() { return Take(content_.size() - pos_, "data"); }

  size_t remaining() const { return content_.size() - pos_; }
  // Where the next field starts.
  uint64_t offset() const { return offset_ + pos_; }
  [[noreturn]] void Fail(const std::string& message) const {
    place_.Fail(offset_ + pos_, opcode_, message);
  }

 private:
  template <typename T>
  T Fixed(const char* field) {
    Need(sizeof(T), field);
    T value;
    std::memcpy(&value, content_.data() + pos_, sizeof(T));  // little-endian host
    pos_ += sizeof(T);
    return value;
  }
  std::string_view Take(uint64_t size, const char* field) {
    Need(size, field);
    std::string_view bytes = content_.substr(pos_, size);
    pos_ += size;
    return bytes;
  }
  void Need(uint64_t size, const char* field) const;

  std::string_view content_;
  size_t pos_ = 0;
  uint64_t offset_;
  uint8_t opcode_;
  const McapPlace& place_;
};

}  // namespace internal
}  // namespace import
}  // namespace autocal
