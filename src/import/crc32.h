#pragma once

// CRC-32 as zlib, PNG and MCAP compute it (IEEE 802.3: reflected polynomial 0xEDB88320,
// initial value and final xor 0xFFFFFFFF). MCAP checks its chunks, attachments, data and
// summary sections with it.

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace autocal {
namespace import {

// Continues a CRC over `size` more bytes: Crc32Update(Crc32Update(0, a), b) equals the CRC
// of a followed by b. Start from 0.
uint32_t Crc32Update(uint32_t crc, const void* data, size_t size);

inline uint32_t Crc32(std::string_view bytes) { return Crc32Update(0, bytes.data(), bytes.size()); }

}  // namespace import
}  // namespace autocal
