#pragma once

// Strict number parsing and exact number formatting shared by the io readers and writers.
// Private to src/io.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace autocal {
namespace io {
namespace internal {

// Shortest decimal text that reads back to exactly the same double (std::to_chars), so
// every writer/reader pair round trips bit for bit.
std::string FormatDouble(double value);

// Parses the whole of `text` as a double; "nan" and "inf" are accepted here (the caller
// decides what to do with them).
bool ParseDouble(std::string_view text, double* value, std::string* why);

// Parses the whole of `text` (no surrounding blanks, no trailing characters) as a finite
// double. On failure returns false and sets *why to a sentence fit for a person
// ("expected a number, found 'abc'", "trailing characters '...' after the number", "NaN
// is not allowed", ...).
bool ParseFiniteDouble(std::string_view text, double* value, std::string* why);

// Same for a base-10 signed 64-bit integer.
bool ParseInt64(std::string_view text, int64_t* value, std::string* why);

// A blank-separated word of a line and its 1-based column.
struct Word {
  std::string_view text;
  int64_t column = 0;
};

// The words of `line`, split at spaces and tabs.
std::vector<Word> SplitWords(std::string_view line);

// `text` without leading and trailing spaces, tabs and carriage returns.
std::string_view Trim(std::string_view text);

// `text` quoted for an error message, cut to a readable length.
std::string Quote(std::string_view text);

// The whole file as bytes; throws autocal::Error naming the path when it cannot be read.
std::string ReadFileBytes(const std::string& path);

// Replaces the file at `path` by `text`, byte for byte and atomically (a temporary file
// beside it, renamed); throws autocal::Error naming the path and the system's reason ("No
// space left on device") when it cannot. No fsync: the io writers write many files (a
// dataset's sweeps), and io::StagedDirectory::Commit syncs them all at once.
void WriteFileText(const std::string& path, const std::string& text);

// The writer behind WriteFileText (sync false) and io::WriteFileAtomically (sync true: fsync
// before the rename). Implemented in output_files.cc.
void WriteFileReplacing(const std::string& path, const std::string& text, bool sync);

// Writes all of `bytes` to the open descriptor `fd` (retrying short writes); throws
// autocal::Error "cannot write '<path>': <reason>" on the first failure.
void WriteAllToDescriptor(int fd, std::string_view bytes, const std::string& path);

}  // namespace internal
}  // namespace io
}  // namespace autocal
