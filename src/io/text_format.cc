#include "io/text_format.h"

#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>

#include "autocal/common/error.h"

namespace autocal {
namespace io {
namespace internal {
namespace {

constexpr size_t kMaxQuotedLength = 40;

// from_chars rejects a leading '+', which other tools happily write.
std::string_view StripPlus(std::string_view text) {
  if (text.size() > 1 && text[0] == '+' && text[1] != '-' && text[1] != '+') {
    return text.substr(1);
  }
  return text;
}

// How error messages name the number a parser expects.
struct NumberKind {
  const char* noun;          // "number 'x' is out of range", "after the number"
  const char* with_article;  // "expected a number"
  const char* out_of_range;  // "number 'x' <out_of_range>"
};

constexpr NumberKind kDoubleKind{"number", "a number", "is out of the range of a double"};
constexpr NumberKind kInt64Kind{"integer", "an integer", "does not fit in 64 bits"};

// The whole of `text` as a T (std::from_chars, which would reject the leading '+' that
// StripPlus removes).
template <typename T>
bool ParseNumber(std::string_view text, const NumberKind& kind, T* value, std::string* why) {
  if (text.empty()) {
    *why = std::string("expected ") + kind.with_article + ", found an empty field";
    return false;
  }
  const std::string_view digits = StripPlus(text);
  const char* end = digits.data() + digits.size();
  const std::from_chars_result result = std::from_chars(digits.data(), end, *value);
  if (result.ec == std::errc::invalid_argument) {
    *why = std::string("expected ") + kind.with_article + ", found " + Quote(text);
    return false;
  }
  if (result.ec == std::errc::result_out_of_range) {
    *why = std::string(kind.noun) + " " + Quote(text) + " " + kind.out_of_range;
    return false;
  }
  if (result.ptr != end) {
    *why = "trailing characters " + Quote(std::string_view(result.ptr, end - result.ptr)) +
           " after the " + kind.noun + " in " + Quote(text);
    return false;
  }
  return true;
}

}  // namespace

std::string FormatDouble(double value) {
  char buffer[64];
  const std::to_chars_result result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

bool ParseDouble(std::string_view text, double* value, std::string* why) {
  return ParseNumber(text, kDoubleKind, value, why);
}

bool ParseFiniteDouble(std::string_view text, double* value, std::string* why) {
  if (!ParseDouble(text, value, why)) return false;
  if (!std::isfinite(*value)) {
    *why = "non-finite value " + Quote(text) + " is not allowed";
    return false;
  }
  return true;
}

bool ParseInt64(std::string_view text, int64_t* value, std::string* why) {
  return ParseNumber(text, kInt64Kind, value, why);
}

std::vector<Word> SplitWords(std::string_view line) {
  std::vector<Word> words;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start)
      words.push_back({line.substr(start, i - start), static_cast<int64_t>(start) + 1});
  }
  return words;
}

std::string_view Trim(std::string_view text) {
  constexpr std::string_view kBlank = " \t\r";
  const size_t first = text.find_first_not_of(kBlank);
  if (first == std::string_view::npos) return {};
  const size_t last = text.find_last_not_of(kBlank);
  return text.substr(first, last - first + 1);
}

std::string Quote(std::string_view text) {
  if (text.size() <= kMaxQuotedLength) return "'" + std::string(text) + "'";
  return "'" + std::string(text.substr(0, kMaxQuotedLength)) + "...'";
}

std::string ReadFileBytes(const std::string& path) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error)) {
    throw Error("cannot read '" + path + "': it is a directory");
  }
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) {
    throw Error("cannot open '" + path + "' for reading: " + std::strerror(errno));
  }
  const std::streamoff size = in.tellg();
  if (size < 0) throw Error("cannot determine the size of '" + path + "'");
  std::string bytes(static_cast<size_t>(size), '\0');
  in.seekg(0);
  in.read(bytes.data(), size);
  if (in.gcount() != size) throw Error("error while reading '" + path + "'");
  return bytes;
}

void WriteFileText(const std::string& path, const std::string& text) {
  WriteFileReplacing(path, text, false);
}

void WriteAllToDescriptor(int fd, std::string_view bytes, const std::string& path) {
  while (!bytes.empty()) {
    const ssize_t written = write(fd, bytes.data(), bytes.size());
    if (written < 0 && errno == EINTR) continue;
    if (written < 0) throw Error("cannot write '" + path + "': " + std::strerror(errno));
    if (written == 0) throw Error("cannot write '" + path + "': the device took no bytes");
    bytes.remove_prefix(static_cast<size_t>(written));
  }
}

}  // namespace internal
}  // namespace io
}  // namespace autocal
