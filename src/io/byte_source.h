#pragma once

// A read position over the bytes of a whole file with its line count, and the error
// reporting of the io readers: every failure is a ParseError naming the file and either a
// line and column or a byte offset. Shared by the PLY, PCD, CSV and TUM readers. Private to
// src/io.

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace autocal {
namespace io {
namespace internal {

class ByteSource {
 public:
  // `bytes` is the whole file and `path` only names it in errors; both must outlive this.
  ByteSource(const std::string& path, const std::string& bytes) : path_(path), bytes_(bytes) {}

  [[noreturn]] void FailAt(int64_t line, int64_t column, const std::string& message) const;
  // At `column` of the line read last.
  [[noreturn]] void FailAtColumn(int64_t column, const std::string& message) const {
    FailAt(line_, column, message);
  }
  [[noreturn]] void FailAtByte(size_t offset, const std::string& message) const;
  // At column 1 of `line` for text data (line > 0), else at `byte_offset` for binary data.
  [[noreturn]] void FailAtLineOrByte(int64_t line, size_t byte_offset,
                                     const std::string& message) const;

  // The next line without its line break (LF or CRLF); counts it and moves past it. False
  // at the end of the file.
  bool NextLine(std::string_view* line);

  // `text`, found at `line` and `column`, parsed as a base-10 integer / a double ("nan" and
  // "inf" accepted); anything else fails there.
  int64_t IntegerAt(std::string_view text, int64_t line, int64_t column) const;
  double DoubleAt(std::string_view text, int64_t line, int64_t column) const;

  const std::string& bytes() const { return bytes_; }
  size_t size() const { return bytes_.size(); }
  // Bytes not read yet.
  size_t remaining() const { return bytes_.size() - pos_; }

  // The read position: the byte offset of the next unread byte, <= size().
  size_t pos() const { return pos_; }
  // `pos` <= size(); beyond it fails like Advance.
  void set_pos(size_t pos);
  // Moves `n` bytes on. Readers check n <= remaining() first to name what is missing; this
  // is the last line of defence and fails at the end of the file ("truncated?").
  void Advance(size_t n);

  // 1-based number of the line read last (0 before the first).
  int64_t line() const { return line_; }
  void set_line(int64_t line) { line_ = line; }

 private:
  const std::string& path_;
  const std::string& bytes_;
  size_t pos_ = 0;
  int64_t line_ = 0;
};

}  // namespace internal
}  // namespace io
}  // namespace autocal
