#include "io/csv_reader.h"

#include <utility>

#include "io/text_format.h"

namespace autocal {
namespace io {
namespace internal {

CsvReader::CsvReader(std::string path, std::vector<std::string> columns)
    : path_(std::move(path)),
      columns_(std::move(columns)),
      bytes_(ReadFileBytes(path_)),
      source_(path_, bytes_) {
  if (bytes_.empty()) FailAt(1, 1, "empty file; expected the header line '" + HeaderText() + "'");
  // Spreadsheet programs may prefix a UTF-8 byte order mark; it is not part of the header.
  source_.set_pos(bytes_.rfind("\xEF\xBB\xBF", 0) == 0 ? 3 : 0);
  std::string_view header;
  source_.NextLine(&header);
  CheckHeader(header);
}

std::string CsvReader::HeaderText() const {
  std::string text;
  for (const std::string& column : columns_) text += (text.empty() ? "" : ",") + column;
  return text;
}

void CsvReader::Split(std::string_view line) {
  fields_.clear();
  line_length_ = line.size();
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    const size_t end = comma == std::string_view::npos ? line.size() : comma;
    const std::string_view raw = line.substr(start, end - start);
    const std::string_view trimmed = Trim(raw);
    const size_t offset =
        trimmed.empty() ? start : static_cast<size_t>(trimmed.data() - line.data());
    fields_.push_back({trimmed, static_cast<int64_t>(offset) + 1});
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
}

void CsvReader::CheckHeader(std::string_view line) {
  if (Trim(line).empty()) {
    FailAt(1, 1, "empty first line; expected the header line '" + HeaderText() + "'");
  }
  Split(line);
  // EuRoC-style headers start with '#'.
  if (!fields_[0].text.empty() && fields_[0].text[0] == '#') {
    const std::string_view after_hash = fields_[0].text.substr(1);
    const std::string_view name = Trim(after_hash);
    // A blank name ("#" alone) is the empty name at the column after the '#'.
    fields_[0].column += name.empty() ? 1 : name.data() - fields_[0].text.data();
    fields_[0].text = name;
  }
  double number = 0.0;
  std::string why;
  if (ParseDouble(fields_[0].text, &number, &why)) {
    FailAt(1, fields_[0].column,
           "missing header line: expected '" + HeaderText() + "', found a data row");
  }
  for (size_t i = 0; i < columns_.size(); ++i) {
    if (i >= fields_.size()) {
      FailAt(1, static_cast<int64_t>(line_length_) + 1,
             "header has " + std::to_string(fields_.size()) + " columns, expected " +
                 std::to_string(columns_.size()) + ": '" + HeaderText() + "'");
    }
    if (fields_[i].text != columns_[i]) {
      FailAt(1, fields_[i].column,
             "header column " + std::to_string(i + 1) + " is " + Quote(fields_[i].text) +
                 ", expected '" + columns_[i] + "' (header '" + HeaderText() + "')");
    }
  }
  if (fields_.size() > columns_.size()) {
    FailAt(1, fields_[columns_.size()].column,
           "header has " + std::to_string(fields_.size()) + " columns, expected " +
               std::to_string(columns_.size()) + ": '" + HeaderText() + "'");
  }
}

bool CsvReader::Next() {
  std::string_view line;
  if (!source_.NextLine(&line)) return false;
  if (Trim(line).empty())
    source_.FailAtColumn(1, "empty line; every line after the header is a data row");
  Split(line);
  if (fields_.size() < columns_.size()) {
    source_.FailAtColumn(static_cast<int64_t>(line_length_) + 1,
                         "expected " + std::to_string(columns_.size()) + " columns (" +
                             HeaderText() + "), found " + std::to_string(fields_.size()));
  }
  if (fields_.size() > columns_.size()) {
    Fail(columns_.size(), "expected " + std::to_string(columns_.size()) + " columns (" +
                              HeaderText() + "), found " + std::to_string(fields_.size()));
  }
  return true;
}

double CsvReader::Double(size_t field) const {
  double value = 0.0;
  std::string why;
  if (!ParseFiniteDouble(fields_[field].text, &value, &why))
    Fail(field, columns_[field] + ": " + why);
  return value;
}

int64_t CsvReader::Int64(size_t field) const {
  int64_t value = 0;
  std::string why;
  if (!ParseInt64(fields_[field].text, &value, &why)) Fail(field, columns_[field] + ": " + why);
  return value;
}

int64_t CsvReader::Timestamp() {
  const int64_t t_ns = Int64(0);
  // Within 2^62 ns (146 years) of 1970, so that any two stamps' difference, and a stamp plus
  // such a difference, stay in int64.
  constexpr int64_t kMaxStampNs = int64_t{1} << 62;
  if (t_ns > kMaxStampNs || t_ns < -kMaxStampNs) {
    Fail(0, "timestamp " + std::to_string(t_ns) +
                " ns is more than 146 years from 1970 (2^62 ns): not a time in nanoseconds");
  }
  if (has_previous_time_ && t_ns <= previous_time_ns_) {
    Fail(0, std::string(t_ns == previous_time_ns_ ? "duplicate" : "non-monotonic") + " timestamp " +
                std::to_string(t_ns) + " ns: the previous row (line " +
                std::to_string(previous_time_line_) + ") has " + std::to_string(previous_time_ns_) +
                " ns; timestamps must strictly increase");
  }
  has_previous_time_ = true;
  previous_time_ns_ = t_ns;
  previous_time_line_ = source_.line();
  return t_ns;
}

void CsvReader::Fail(size_t field, const std::string& message) const {
  source_.FailAtColumn(fields_[field].column, message);
}

void CsvReader::FailAt(int64_t line, int64_t column, const std::string& message) const {
  source_.FailAt(line, column, message);
}

}  // namespace internal
}  // namespace io
}  // namespace autocal
