#include "import/mcap_decompress.h"

#include <lz4frame.h>
#include <zstd.h>
#include <zstd_errors.h>

namespace autocal {
namespace import {
namespace internal {

struct Decompressor::Contexts {
  ZSTD_DCtx* zstd = nullptr;
  LZ4F_dctx* lz4 = nullptr;
};

Decompressor::Decompressor() : contexts_(std::make_unique<Contexts>()) {}

Decompressor::~Decompressor() {
  if (contexts_->zstd != nullptr) ZSTD_freeDCtx(contexts_->zstd);
  if (contexts_->lz4 != nullptr) LZ4F_freeDecompressionContext(contexts_->lz4);
}

std::string Decompressor::Decompress(std::string_view format, std::string_view compressed,
                                     char* out, size_t size) {
  if (format == "zstd") return DecompressZstd(compressed, out, size);
  if (format == "lz4") return DecompressLz4(compressed, out, size);
  return "unknown compression '" + std::string(format) + "'";
}

std::string Decompressor::DecompressZstd(std::string_view compressed, char* out, size_t size) {
  if (contexts_->zstd == nullptr) contexts_->zstd = ZSTD_createDCtx();
  if (contexts_->zstd == nullptr) return "cannot create a zstd context";
  // Several concatenated frames are decompressed one after the other.
  const size_t written =
      ZSTD_decompressDCtx(contexts_->zstd, out, size, compressed.data(), compressed.size());
  if (ZSTD_isError(written)) {
    if (ZSTD_getErrorCode(written) == ZSTD_error_dstSize_tooSmall) {
      return "zstd data decompresses to more than the declared " + std::to_string(size) + " bytes";
    }
    return std::string("zstd: ") + ZSTD_getErrorName(written);
  }
  if (written != size) {
    return "zstd data decompresses to " + std::to_string(written) + " bytes, not the declared " +
           std::to_string(size);
  }
  return "";
}

std::string Decompressor::DecompressLz4(std::string_view compressed, char* out, size_t size) {
  if (contexts_->lz4 == nullptr &&
      LZ4F_isError(LZ4F_createDecompressionContext(&contexts_->lz4, LZ4F_VERSION))) {
    contexts_->lz4 = nullptr;
    return "cannot create an lz4 context";
  }
  LZ4F_dctx* context = contexts_->lz4;
  size_t in_pos = 0;
  size_t out_pos = 0;
  size_t hint = 0;  // 0: between frames
  std::string error;
  while (in_pos < compressed.size()) {
    size_t in_size = compressed.size() - in_pos;
    size_t out_size = size - out_pos;
    hint = LZ4F_decompress(context, out + out_pos, &out_size, compressed.data() + in_pos, &in_size,
                           nullptr);
    if (LZ4F_isError(hint)) {
      error = std::string("lz4: ") + LZ4F_getErrorName(hint);
      break;
    }
    in_pos += in_size;
    out_pos += out_size;
    if (hint != 0 && in_size == 0 && out_size == 0) break;  // no progress: output is full
  }
  if (error.empty() && hint != 0) {
    error = out_pos == size ? "lz4 data decompresses to more than the declared " +
                                  std::to_string(size) + " bytes"
                            : "lz4 frame ends early (truncated data)";
  }
  if (error.empty() && out_pos != size) {
    error = "lz4 data decompresses to " + std::to_string(out_pos) + " bytes, not the declared " +
            std::to_string(size);
  }
  if (!error.empty()) LZ4F_resetDecompressionContext(context);
  return error;
}

}  // namespace internal
}  // namespace import
}  // namespace autocal
