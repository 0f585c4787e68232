#pragma once

// A read-only memory map of a whole file. The MCAP reader walks records in place through it:
// no copy of the file is held, and the kernel pages it in (sequential read-ahead) and out as
// the scan moves, so memory stays bounded by the largest decompressed chunk.

#include <cstddef>
#include <string>
#include <string_view>

namespace autocal {
namespace import {
namespace internal {

class MappedFile {
 public:
  // Throws autocal::Error when the file cannot be opened or mapped. An empty file maps to
  // an empty view.
  explicit MappedFile(const std::string& path);
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  std::string_view bytes() const { return {data_, size_}; }

 private:
  const char* data_ = nullptr;
  size_t size_ = 0;
};

}  // namespace internal
}  // namespace import
}  // namespace autocal
