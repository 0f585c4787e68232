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

// Decompresses `compressed` into `*out`, at most `limit` bytes (one more means "more than
// declared"). Sets *ended when the stream's end mark was read and *unused to the input bytes
// after it. Data that runs out before the end mark is an error unless `cut_ok`. Returns an
// empty string, or what is wrong with the data.
std::string Bz2Decompress(std::string_view compressed, size_t limit, bool cut_ok, std::string* out,
                          bool* ended, size_t* unused) {
  *ended = false;
  if (compressed.size() > UINT_MAX || limit > UINT_MAX) return "bz2 chunk larger than 4 GiB";
  bz_stream stream;
  std::memset(&stream, 0, sizeof(stream));
  if (BZ2_bzDecompressInit(&stream, /*verbosity=*/0, /*small=*/0) != BZ_OK) {
    return "cannot start bz2 decompression";
  }
  std::unique_ptr<bz_stream, int (*)(bz_stream*)> end(&stream, &BZ2_bzDecompressEnd);
  stream.next_in = const_cast<char*>(compressed.data());
  stream.avail_in = static_cast<unsigned int>(compressed.size());
  out->resize(FirstOutputSize(compressed.size(), limit));
  size_t produced = 0;
  for (;;) {
    stream.next_out = out->data() + produced;
    stream.avail_out = static_cast<unsigned int>(out->size() - produced);
    const int status = BZ2_bzDecompress(&stream);
    produced = out->size() - stream.avail_out;
    if (status == BZ_STREAM_END) {
      *ended = true;
      break;
    }
    if (status != BZ_OK) {
      return "bz2 data is corrupt (libbz2 error " + std::to_string(status) + ")";
    }
    if (stream.avail_out == 0) {
      if (out->size() == limit) break;  // the caller tells the sizes apart
      out->resize(std::min(limit, 2 * out->size()));
    } else if (stream.avail_in == 0) {
      if (cut_ok) break;
      return "bz2 data is truncated (the stream's end is missing)";
    }
  }
  out->resize(produced);
  *unused = stream.avail_in;
  return "";
}

std::string Lz4FrameDecompress(std::string_view compressed, size_t limit, bool cut_ok,
                               std::string* out, bool* ended, size_t* unused) {
  *ended = false;
  LZ4F_dctx* raw_context = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&raw_context, LZ4F_VERSION))) {
    return "cannot create an LZ4 decompression context";
  }
  std::unique_ptr<LZ4F_dctx, decltype(&LZ4F_freeDecompressionContext)> context(
      raw_context, &LZ4F_freeDecompressionContext);
  out->resize(FirstOutputSize(compressed.size(), limit));
  size_t in_pos = 0;
  size_t out_pos = 0;
  size_t hint = 1;
  while (in_pos < compressed.size() && hint != 0) {
    if (out_pos == out->size()) {
      if (out_pos == limit) break;  // the caller tells the sizes apart
      out->resize(std::min(limit, 2 * out->size()));
    }
    size_t in_size = compressed.size() - in_pos;
    size_t out_size = out->size() - out_pos;
    hint = LZ4F_decompress(context.get(), out->data() + out_pos, &out_size,
                           compressed.data() + in_pos, &in_size, nullptr);
    if (LZ4F_isError(hint)) {
      return std::string("lz4 frame data is corrupt: ") + LZ4F_getErrorName(hint);
    }
    in_pos += in_size;
    out_pos += out_size;
    if (in_size == 0 && out_size == 0) break;  // no progress: needs input it does not have
  }
  out->resize(out_pos);
  *ended = hint == 0;
  *unused = compressed.size() - in_pos;
  if (!*ended && !cut_ok && out_pos < limit) {
    return "lz4 frame is truncated (the frame's end mark is missing)";
  }
  return "";
}

using Decompressor = std::string (*)(std::string_view, size_t, bool, std::string*, bool*, size_t*);

// The stream must decompress to exactly `expected_bytes` and fill the chunk's data.
std::string DecompressWhole(Decompressor decompress, const char* name, const char* stream_name,
                            std::string_view compressed, size_t expected_bytes, std::string* out) {
  bool ended = false;
  size_t unused = 0;
  const std::string why =
      decompress(compressed, expected_bytes + 1, /*cut_ok=*/false, out, &ended, &unused);
  if (!why.empty()) return why;
  if (out->size() > expected_bytes) {
    return std::string(name) + " data decompresses to more than the chunk's declared size of " +
           std::to_string(expected_bytes) + " bytes";
  }
  if (out->size() != expected_bytes) {
    return std::string(name) + " data decompresses to " + std::to_string(out->size()) +
           " bytes but the chunk declares " + std::to_string(expected_bytes);
  }
  if (unused != 0) return TrailingBytes(stream_name, unused);
  return "";
}

// As much of a stream cut short as it holds in whole blocks.
std::string DecompressCut(Decompressor decompress, const char* name, std::string_view compressed,
                          size_t limit, std::string* out, bool* ended) {
  size_t unused = 0;
  const std::string why = decompress(compressed, limit + 1, /*cut_ok=*/true, out, ended, &unused);
  if (!why.empty()) return why;
  if (out->size() > limit) {
    return std::string(name) + " data decompresses to more than " + std::to_string(limit) +
           " bytes";
  }
  return "";
}

}  // namespace

std::string DecompressBz2Chunk(std::string_view compressed, size_t expected_bytes,
                               std::string* out) {
  return DecompressWhole(&Bz2Decompress, "bz2", "bz2 stream", compressed, expected_bytes, out);
}

std::string DecompressLz4FrameChunk(std::string_view compressed, size_t expected_bytes,
                                    std::string* out) {
  return DecompressWhole(&Lz4FrameDecompress, "lz4", "lz4 frame", compressed, expected_bytes, out);
}

std::string DecompressCutBz2Chunk(std::string_view compressed, size_t limit, std::string* out,
                                  bool* ended) {
  return DecompressCut(&Bz2Decompress, "bz2", compressed, limit, out, ended);
}

std::string DecompressCutLz4FrameChunk(std::string_view compressed, size_t limit, std::string* out,
                                       bool* ended) {
  return DecompressCut(&Lz4FrameDecompress, "lz4", compressed, limit, out, ended);
}

}  // namespace import
}  // namespace autocal
