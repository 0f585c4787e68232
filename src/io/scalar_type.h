#pragma once

// The numeric property/field types of PLY and PCD files and how to decode them from raw
// bytes of either endianness. Private to src/io.

#include <cstdint>
#include <cstring>
#include <optional>
#include <string>
#include <utility>

namespace autocal {
namespace io {
namespace internal {

enum class ScalarType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

inline size_t ScalarSize(ScalarType type) {
  switch (type) {
    case ScalarType::kInt8:
    case ScalarType::kUint8:
      return 1;
    case ScalarType::kInt16:
    case ScalarType::kUint16:
      return 2;
    case ScalarType::kInt32:
    case ScalarType::kUint32:
    case ScalarType::kFloat32:
      return 4;
    case ScalarType::kFloat64:
      return 8;
  }
  return 0;
}

inline bool IsIntegerType(ScalarType type) {
  return type != ScalarType::kFloat32 && type != ScalarType::kFloat64;
}

inline bool HostIsLittleEndian() {
  const uint16_t one = 1;
  unsigned char first_byte = 0;
  std::memcpy(&first_byte, &one, 1);
  return first_byte == 1;
}

// The T stored in host byte order at `buffer` (memcpy: `buffer` need not be aligned).
template <typename T>
double LoadAs(const unsigned char* buffer) {
  T value;
  std::memcpy(&value, buffer, sizeof(T));
  return static_cast<double>(value);
}

// Reads one value of `type` from `bytes`, stored little endian when `little_endian`.
inline double DecodeScalar(const char* bytes, ScalarType type, bool little_endian) {
  unsigned char buffer[8];
  const size_t size = ScalarSize(type);
  std::memcpy(buffer, bytes, size);
  if (little_endian != HostIsLittleEndian()) {
    for (size_t i = 0; i < size / 2; ++i) std::swap(buffer[i], buffer[size - 1 - i]);
  }
  switch (type) {
    case ScalarType::kInt8:
      return LoadAs<int8_t>(buffer);
    case ScalarType::kUint8:
      return LoadAs<uint8_t>(buffer);
    case ScalarType::kInt16:
      return LoadAs<int16_t>(buffer);
    case ScalarType::kUint16:
      return LoadAs<uint16_t>(buffer);
    case ScalarType::kInt32:
      return LoadAs<int32_t>(buffer);
    case ScalarType::kUint32:
      return LoadAs<uint32_t>(buffer);
    case ScalarType::kFloat32:
      return LoadAs<float>(buffer);
    case ScalarType::kFloat64:
      return LoadAs<double>(buffer);
  }
  return 0.0;
}

// PLY type names, both the classic ones (char, uchar, ...) and the sized aliases (int8,
// uint8, ..., float32, float64).
inline std::optional<ScalarType> PlyScalarType(const std::string& name) {
  if (name == "char" || name == "int8") return ScalarType::kInt8;
  if (name == "uchar" || name == "uint8") return ScalarType::kUint8;
  if (name == "short" || name == "int16") return ScalarType::kInt16;
  if (name == "ushort" || name == "uint16") return ScalarType::kUint16;
  if (name == "int" || name == "int32") return ScalarType::kInt32;
  if (name == "uint" || name == "uint32") return ScalarType::kUint32;
  if (name == "float" || name == "float32") return ScalarType::kFloat32;
  if (name == "double" || name == "float64") return ScalarType::kFloat64;
  return std::nullopt;
}

}  // namespace internal
}  // namespace io
}  // namespace autocal
