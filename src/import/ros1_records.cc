#include "import/ros1_records.h"

#include <fcntl.h>
#include <unistd.h>

namespace autocal {
namespace import {
namespace ros1 {

std::string OpName(int op) {
  switch (op) {
    case kMessageData:
      return "message data record";
    case kBagHeader:
      return "bag header record";
    case kIndexData:
      return "index data record";
    case kChunk:
      return "chunk record";
    case kChunkInfo:
      return "chunk info record";
    case kConnection:
      return "connection record";
    default:
      return "record";
  }
}

bool HeaderFields::Parse(std::string_view bytes, std::string* why) {
  fields_.clear();
  size_t pos = 0;
  while (pos < bytes.size()) {
    if (bytes.size() - pos < 4) {
      *why = "header field length cut off at header byte " + std::to_string(pos);
      return false;
    }
    const uint32_t length = LoadU32(bytes.data() + pos);
    pos += 4;
    if (length > bytes.size() - pos) {
      *why = "header field at header byte " + std::to_string(pos - 4) + " declares " +
             std::to_string(length) + " bytes, only " + std::to_string(bytes.size() - pos) +
             " left in the header";
      return false;
    }
    const std::string_view field = bytes.substr(pos, length);
    const size_t equals = field.find('=');
    if (equals == std::string_view::npos) {
      *why = "header field at header byte " + std::to_string(pos - 4) + " has no '='";
      return false;
    }
    fields_.emplace_back(field.substr(0, equals), field.substr(equals + 1));
    pos += length;
  }
  return true;
}

FileDescriptor::~FileDescriptor() {
  if (fd_ >= 0) ::close(fd_);
}

void FileDescriptor::Open(const std::string& path) {
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
}

}  // namespace ros1
}  // namespace import
}  // namespace autocal
