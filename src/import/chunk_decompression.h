#pragma once

// Decompression of one ROS 1 bag chunk into a buffer of the size the chunk declares.
// "bz2" chunks are bzip2 streams; "lz4" chunks are LZ4 *frames* (the frame format with
// magic 0x184D2204 and a content checksum, which ROS 1's roslz4 writes), not raw LZ4
// blocks. Private to src/import.

#include <string>
#include <string_view>

namespace autocal {
namespace import {

// Decompresses `compressed` into `*out`, which must come out exactly `expected_bytes`
// long. Returns an empty string on success, else a sentence saying what went wrong (the
// caller adds the file and byte offset).
std::string DecompressBz2Chunk(std::string_view compressed, size_t expected_bytes,
                               std::string* out);
std::string DecompressLz4FrameChunk(std::string_view compressed, size_t expected_bytes,
                                    std::string* out);

// The open chunk a recorder stopped mid-write leaves: a stream cut short, of unknown size.
// Decompresses what its whole blocks hold into `*out` (more than `limit` bytes is an error);
// *ended tells whether the stream's end mark was there after all. Returns an empty string,
// or what is wrong with the data (corrupt, not merely cut).
std::string DecompressCutBz2Chunk(std::string_view compressed, size_t limit, std::string* out,
                                  bool* ended);
std::string DecompressCutLz4FrameChunk(std::string_view compressed, size_t limit, std::string* out,
                                       bool* ended);

}  // namespace import
}  // namespace autocal
