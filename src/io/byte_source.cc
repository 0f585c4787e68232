#include "io/byte_source.h"

#include "autocal/common/error.h"
#include "io/text_format.h"

namespace autocal {
namespace io {
namespace internal {

void ByteSource::FailAt(int64_t line, int64_t column, const std::string& message) const {
  SourceLocation location;
  location.file = path_;
  location.line = line;
  location.column = column;
  throw ParseError(location, message);
}

void ByteSource::FailAtByte(size_t offset, const std::string& message) const {
  SourceLocation location;
  location.file = path_;
  location.byte_offset = static_cast<int64_t>(offset);
  throw ParseError(location, message);
}

void ByteSource::FailAtLineOrByte(int64_t line, size_t byte_offset,
                                  const std::string& message) const {
  if (line > 0) FailAt(line, 1, message);
  FailAtByte(byte_offset, message);
}

void ByteSource::set_pos(size_t pos) {
  if (pos > bytes_.size()) {
    FailAtByte(bytes_.size(), "file ends at byte " + std::to_string(bytes_.size()) +
                                  ", before byte " + std::to_string(pos) + ": truncated?");
  }
  pos_ = pos;
}

void ByteSource::Advance(size_t n) {
  if (n > remaining()) {
    FailAtByte(bytes_.size(), "file ends at byte " + std::to_string(bytes_.size()) + ", " +
                                  std::to_string(n - remaining()) +
                                  " bytes short of the data declared after byte " +
                                  std::to_string(pos_) + ": truncated?");
  }
  pos_ += n;
}

bool ByteSource::NextLine(std::string_view* line) {
  if (pos_ >= bytes_.size()) return false;
  size_t end = bytes_.find('\n', pos_);
  const size_t next = end == std::string::npos ? bytes_.size() : end + 1;
  if (end == std::string::npos) end = bytes_.size();
  *line = std::string_view(bytes_).substr(pos_, end - pos_);
  if (!line->empty() && line->back() == '\r') line->remove_suffix(1);
  pos_ = next;
  ++line_;
  return true;
}

int64_t ByteSource::IntegerAt(std::string_view text, int64_t line, int64_t column) const {
  int64_t value = 0;
  std::string why;
  if (!ParseInt64(text, &value, &why)) FailAt(line, column, why);
  return value;
}

double ByteSource::DoubleAt(std::string_view text, int64_t line, int64_t column) const {
  double value = 0.0;
  std::string why;
  if (!ParseDouble(text, &value, &why)) FailAt(line, column, why);
  return value;
}

}  // namespace internal
}  // namespace io
}  // namespace autocal
