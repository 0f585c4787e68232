#include "import/chunk_decompression.h"

#include <bzlib.h>
#include <lz4frame.h>

#include <algorithm>
#include <climits>
#include <cstring>
#include <memory>

namespace autocal {
namespace import {
namespace {

// The first size of a decompression buffer that grows as the data comes out, so that a chunk
// lying about its size costs no more memory than its data really holds; `limit` is one byte
// beyond the declared size, which tells "more than declared" from "exactly declared".
size_t FirstOutputSize(size_t compressed_bytes, size_t limit) {
  return std::min(limit, std::max<size_t>(4 * compressed_bytes, 1 << 20));
}

// Bytes of a chunk after its compressed stream ended: the chunk's length is not its stream's,
// and the records after the chunk would be read from the wrong place.
std::string TrailingBytes(const char* stream, size_t bytes) {
  return std::string("the ") + stream + " ends " + std::to_string(bytes) +
         " bytes before the chunk's data does (a chunk length that does not match its data)";
}

}  // namespace

std::string DecompressBz2Chunk(std::string_view compressed, size_t expected_bytes,
                               std::string* out) {
  if (compressed.size() > UINT_MAX || expected_bytes >= UINT_MAX) {
    return "bz2 chunk larger than 4 GiB";
  }
  bz_stream stream;
  std::memset(&stream, 0, sizeof(stream));
  if (BZ2_bzDecompressInit(&stream, /*verbosity=*/0, /*small=*/0) != BZ_OK) {
    return "cannot start bz2 decompression";
  }
  std::unique_ptr<bz_stream, int (*)(bz_stream*)> end(&stream, &BZ2_bzDecompressEnd);
  stream.next_in = const_cast<char*>(compressed.data());
  stream.avail_in = static_cast<unsigned int>(compressed.size());
  const size_t limit = expected_bytes + 1;
  out->resize(FirstOutputSize(compressed.size(), limit));
  size_t produced = 0;
  for (;;) {
    stream.next_out = out->data() + produced;
    stream.avail_out = static_cast<unsigned int>(out->size() - produced);
    const int status = BZ2_bzDecompress(&stream);
    produced = out->size() - stream.avail_out;
    if (status == BZ_STREAM_END) break;
    if (status != BZ_OK) {
      return "bz2 data is corrupt (libbz2 error " + std::to_string(status) + ")";
    }
    if (stream.avail_out == 0) {
      if (out->size() == limit) {
        return "bz2 data decompresses to more than the chunk's declared size of " +
               std::to_string(expected_bytes) + " bytes";
      }
      out->resize(std::min(limit, 2 * out->size()));
    } else if (stream.avail_in == 0) {
      return "bz2 data is truncated (the stream's end is missing)";
    }
  }
  if (produced != expected_bytes) {
    return "bz2 data decompresses to " + std::to_string(produced) +
           " bytes but the chunk declares " + std::to_string(expected_bytes);
  }
  if (stream.avail_in != 0) return TrailingBytes("bz2 stream", stream.avail_in);
  out->resize(produced);
  return "";
}

std::string DecompressLz4FrameChunk(std::string_view compressed, size_t expected_bytes,
                                    std::string* out) {
  LZ4F_dctx* raw_context = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&raw_context, LZ4F_VERSION))) {
    return "cannot create an LZ4 decompression context";
  }
  std::unique_ptr<LZ4F_dctx, decltype(&LZ4F_freeDecompressionContext)> context(
      raw_context, &LZ4F_freeDecompressionContext);
  const size_t limit = expected_bytes + 1;
  out->resize(FirstOutputSize(compressed.size(), limit));
  size_t in_pos = 0;
  size_t out_pos = 0;
  size_t hint = 1;
  while (in_pos < compressed.size() && hint != 0) {
    if (out_pos == out->size()) out->resize(std::min(limit, 2 * out->size()));
    size_t in_size = compressed.size() - in_pos;
    size_t out_size = out->size() - out_pos;
    hint = LZ4F_decompress(context.get(), out->data() + out_pos, &out_size,
                           compressed.data() + in_pos, &in_size, nullptr);
    if (LZ4F_isError(hint)) {
      return std::string("lz4 frame data is corrupt: ") + LZ4F_getErrorName(hint);
    }
    in_pos += in_size;
    out_pos += out_size;
    if (out_pos > expected_bytes) {
      return "lz4 data decompresses to more than the chunk's declared size of " +
             std::to_string(expected_bytes) + " bytes";
    }
    if (in_size == 0 && out_size == 0) break;  // no progress: needs input it does not have
  }
  if (hint != 0) return "lz4 frame is truncated (the frame's end mark is missing)";
  if (out_pos != expected_bytes) {
    return "lz4 data decompresses to " + std::to_string(out_pos) +
           " bytes but the chunk declares " + std::to_string(expected_bytes);
  }
  if (in_pos != compressed.size()) return TrailingBytes("lz4 frame", compressed.size() - in_pos);
  out->resize(out_pos);
  return "";
}

}  // namespace import
}  // namespace autocal
