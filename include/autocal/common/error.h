#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

namespace autocal {

// Base of every error autocal reports. The message is complete and meant for a person:
// it says what was expected and, for data, where (see ParseError).
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

// Where in an input a problem was found. line and column are 1-based; 0 means "not
// applicable" (e.g. a binary file uses byte_offset instead).
struct SourceLocation {
  std::string file;
  int64_t line = 0;
  int64_t column = 0;
  int64_t byte_offset = -1;

  // "file:line:column", "file:line", "file: byte N" or "file", whichever applies.
  std::string ToString() const;
};

// Malformed or implausible input. what() reads "<location>: <message>", e.g.
// "data/imu.csv:17:3: expected a number, found 'abc'".
class ParseError : public Error {
 public:
  ParseError(SourceLocation location, const std::string& message);
  const SourceLocation& location() const { return location_; }
  // The message without the location prefix.
  const std::string& detail() const { return detail_; }

 private:
  SourceLocation location_;
  std::string detail_;
};

}  // namespace autocal
