#include "import/mcap_format.h"

#include <cstdio>
#include <limits>

#include "autocal/common/error.h"

namespace autocal {
namespace import {
namespace internal {

std::string Hex(uint32_t value) {
  char text[16];
  std::snprintf(text, sizeof(text), "0x%08X", value);
  return text;
}

std::string McapRecordName(uint8_t opcode) {
  switch (opcode) {
    case kOpHeader:
      return "Header";
    case kOpFooter:
      return "Footer";
    case kOpSchema:
      return "Schema";
    case kOpChannel:
      return "Channel";
    case kOpMessage:
      return "Message";
    case kOpChunk:
      return "Chunk";
    case kOpMessageIndex:
      return "Message Index";
    case kOpChunkIndex:
      return "Chunk Index";
    case kOpAttachment:
      return "Attachment";
    case kOpAttachmentIndex:
      return "Attachment Index";
    case kOpStatistics:
      return "Statistics";
    case kOpMetadata:
      return "Metadata";
    case kOpMetadataIndex:
      return "Metadata Index";
    case kOpSummaryOffset:
      return "Summary Offset";
    case kOpDataEnd:
      return "Data End";
  }
  char name[32];
  std::snprintf(name, sizeof(name), "unknown (opcode 0x%02X)", opcode);
  return name;
}

void McapPlace::Fail(uint64_t offset, uint8_t opcode, const std::string& message) const {
  SourceLocation location;
  location.file = *path;
  std::string where = McapRecordName(opcode) + " record";
  if (chunk_offset >= 0) {
    location.byte_offset = chunk_offset;
    where += " at byte " + std::to_string(offset) + " of the chunk's uncompressed records";
  } else {
    location.byte_offset = static_cast<int64_t>(offset);
  }
  throw ParseError(location, where + ": " + message);
}

int64_t McapFields::Time(const char* field) {
  const uint64_t time_ns = U64(field);
  if (time_ns > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) {
    Fail(std::string(field) + " " + std::to_string(time_ns) + " ns is beyond the int64 range");
  }
  return static_cast<int64_t>(time_ns);
}

void McapFields::Need(uint64_t size, const char* field) const {
  if (size > content_.size() - pos_) {
    Fail(std::string("field ") + field + " needs " + std::to_string(size) +
         " bytes, the record has " + std::to_string(content_.size() - pos_) +
         " left (truncated or a wrong length)");
  }
}

}  // namespace internal
}  // namespace import
}  // namespace autocal
