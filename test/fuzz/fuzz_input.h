#pragma once

// Shared by the libFuzzer targets: hands the fuzzer's bytes to a file reader and accepts
// autocal's own errors as the expected answer to bad input. Any other exception escapes
// and aborts the run (libFuzzer reports it as a crash), as do sanitizer findings.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace fuzz {

// A per-process scratch file ending in `suffix` (readers choose the format by extension);
// TMPDIR when set, else /tmp. Removed when the process exits normally.
inline const std::string& ScratchPath(const std::string& suffix) {
  struct ScratchFile {
    std::string path;
    ~ScratchFile() { std::remove(path.c_str()); }
  };
  static const ScratchFile file{[&] {
    const char* dir = std::getenv("TMPDIR");
    return std::string(dir != nullptr && *dir != '\0' ? dir : "/tmp") + "/autocal_fuzz_" +
           std::to_string(static_cast<long>(getpid())) + suffix;
  }()};
  return file.path;
}

// Writes `size` bytes at `data` to `path`; aborts when it cannot (not an input problem).
inline void WriteScratch(const std::string& path, const uint8_t* data, size_t size) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) std::abort();
  if (size > 0 && std::fwrite(data, 1, size, file) != size) std::abort();
  if (std::fclose(file) != 0) std::abort();
}

// Runs `read` and swallows autocal::Error (a refused input); nothing else.
template <typename Read>
void ExpectParsedOrRefused(Read read) {
  try {
    read();
  } catch (const Error&) {
  }
}

}  // namespace fuzz
}  // namespace autocal
