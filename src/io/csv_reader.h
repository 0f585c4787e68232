#pragma once

// Strict reader for autocal's CSV files: one header line naming the columns (checked),
// then rows with exactly that many comma-separated fields. Every problem is a ParseError
// with file, line and the 1-based column (character position) of the offending field.
// Private to src/io.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "io/byte_source.h"

namespace autocal {
namespace io {
namespace internal {

class CsvReader {
 public:
  // Reads `path` and checks its header against `columns`. Throws autocal::Error when the
  // file cannot be read, ParseError on an empty file or a wrong header.
  CsvReader(std::string path, std::vector<std::string> columns);
  // source_ refers to path_ and bytes_ of this object.
  CsvReader(const CsvReader&) = delete;
  CsvReader& operator=(const CsvReader&) = delete;

  // Advances to the next data row; false after the last one.
  bool Next();

  int64_t line() const { return source_.line(); }
  int64_t column(size_t field) const { return fields_[field].column; }
  const std::string& path() const { return path_; }
  // "t_ns,gx,..." for messages.
  std::string HeaderText() const;

  std::string_view Text(size_t field) const { return fields_[field].text; }
  // A finite number.
  double Double(size_t field) const;
  int64_t Int64(size_t field) const;
  // Field 0 as int64 nanoseconds, strictly greater than the previous row's.
  int64_t Timestamp();

  [[noreturn]] void Fail(size_t field, const std::string& message) const;
  [[noreturn]] void FailAt(int64_t line, int64_t column, const std::string& message) const;

 private:
  struct Field {
    std::string_view text;
    int64_t column = 0;
  };

  // Splits `line` at commas into fields_ (trimmed, with columns).
  void Split(std::string_view line);
  void CheckHeader(std::string_view line);

  std::string path_;
  std::vector<std::string> columns_;
  std::string bytes_;
  ByteSource source_;  // over path_ and bytes_, so declared after them
  size_t line_length_ = 0;
  std::vector<Field> fields_;
  bool has_previous_time_ = false;
  int64_t previous_time_ns_ = 0;
  int64_t previous_time_line_ = 0;
};

}  // namespace internal
}  // namespace io
}  // namespace autocal
