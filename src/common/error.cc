#include "autocal/common/error.h"

#include <utility>

namespace autocal {

std::string SourceLocation::ToString() const {
  std::string out = file;
  if (line > 0) {
    out += ":" + std::to_string(line);
    if (column > 0) out += ":" + std::to_string(column);
  } else if (byte_offset >= 0) {
    out += ": byte " + std::to_string(byte_offset);
  }
  return out;
}

ParseError::ParseError(SourceLocation location, const std::string& message)
    : Error(location.ToString() + ": " + message),
      location_(std::move(location)),
      detail_(message) {}

}  // namespace autocal
