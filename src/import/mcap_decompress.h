#pragma once

// The chunk codecs of MCAP ("zstd", "lz4" as LZ4 frames), also used for rosbag2's
// per-message zstd compression. Decompression writes into a caller's buffer of the declared
// size and fails when the data decompresses to anything else, so a chunk that lies about its
// size is caught without trusting it.

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

namespace autocal {
namespace import {
namespace internal {

class Decompressor {
 public:
  Decompressor();
  ~Decompressor();
  Decompressor(const Decompressor&) = delete;
  Decompressor& operator=(const Decompressor&) = delete;

  static bool Supports(std::string_view format) { return format == "zstd" || format == "lz4"; }

  // Decompresses `compressed` (format "zstd" or "lz4") into exactly `size` bytes at `out`.
  // Returns "" on success, else what went wrong ("decompresses to more than the declared
  // 100 bytes", the codec's own message, ...).
  std::string Decompress(std::string_view format, std::string_view compressed, char* out,
                         size_t size);

 private:
  std::string DecompressZstd(std::string_view compressed, char* out, size_t size);
  std::string DecompressLz4(std::string_view compressed, char* out, size_t size);

  struct Contexts;
  std::unique_ptr<Contexts> contexts_;
};

// A grow-only byte buffer that does not zero what it allocates (a chunk's declared size is
// only trusted after it decompressed to exactly that).
class ByteBuffer {
 public:
  char* Reserve(size_t size) {
    if (size > capacity_) {
      data_.reset(new char[size]);
      capacity_ = size;
    }
    return data_.get();
  }

 private:
  std::unique_ptr<char[]> data_;
  size_t capacity_ = 0;
};

}  // namespace internal
}  // namespace import
}  // namespace autocal
