#pragma once

// A read position over one serialized ROS message, for both serializations autocal
// imports:
//   ROS 1: packed little-endian, no alignment; a string is a u32 byte count and the bytes
//          (no NUL); a sequence is a u32 element count and the elements.
//   CDR:   as ROS 2 writes it: a 4-byte encapsulation header (00 01 = little-endian CDR),
//          then every primitive aligned to its own size, counted from the byte after the
//          header; a string is a u32 count INCLUDING a final NUL and the bytes; a sequence a
//          u32 element count.
// Fixed-size arrays have no count in either. Every read checks the bounds and throws one
// ParseError naming the bag, the record's byte offset, the message type and the offset
// inside the message where the field did not fit. Private to src/import.

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <type_traits>

#include "import/bag_reader.h"

namespace autocal {
namespace import {

// The ROS name of a primitive, for error messages.
template <typename T>
constexpr const char* PrimitiveName() {
  if constexpr (std::is_same_v<T, uint8_t>) return "uint8";
  if constexpr (std::is_same_v<T, int8_t>) return "int8";
  if constexpr (std::is_same_v<T, uint16_t>) return "uint16";
  if constexpr (std::is_same_v<T, uint32_t>) return "uint32";
  if constexpr (std::is_same_v<T, int32_t>) return "int32";
  if constexpr (std::is_same_v<T, uint64_t>) return "uint64";
  if constexpr (std::is_same_v<T, float>) return "float32";
  if constexpr (std::is_same_v<T, double>) return "float64";
  return "primitive";
}

// Where a message came from, for error messages.
struct MessageContext {
  SourceLocation location;  // the bag and where the message sits in it
  std::string type;         // "sensor_msgs/Imu"
  std::string topic;
};

class MessageCursor {
 public:
  // Reads the CDR encapsulation header when `serialization` is kCdr (refusing anything but
  // little-endian plain CDR).
  MessageCursor(std::string_view data, Serialization serialization, const MessageContext* context);

  uint8_t U8() { return Read<uint8_t>(); }
  int8_t I8() { return Read<int8_t>(); }
  uint16_t U16() { return Read<uint16_t>(); }
  uint32_t U32() { return Read<uint32_t>(); }
  int32_t I32() { return Read<int32_t>(); }
  uint64_t U64() { return Read<uint64_t>(); }
  float F32() { return Read<float>(); }
  double F64() { return Read<double>(); }
  bool Bool() { return Read<uint8_t>() != 0; }

  // A string's bytes (without the CDR NUL); the view points into the message.
  std::string_view String();
  // A sequence's element count, checked against the bytes left: each element takes at
  // least `min_element_bytes`.
  uint32_t SequenceCount(size_t min_element_bytes);
  // `count` raw bytes (a uint8[] payload); the view points into the message.
  std::string_view Bytes(size_t count);
  // Moves past `count` primitives of `element_bytes` each (a fixed array), aligned once.
  void SkipArray(size_t count, size_t element_bytes);

  // A header stamp: ROS 1 u32 seq, u32 sec, u32 nsec, string frame_id; ROS 2 int32 sec,
  // u32 nanosec, string frame_id. Returns nanoseconds; `frame_id` may be null.
  int64_t Header(std::string* frame_id);

  Serialization serialization() const { return serialization_; }
  // Bytes of the message not read yet.
  size_t remaining() const { return data_.size() - pos_; }
  size_t position() const { return pos_; }

  [[noreturn]] void Fail(const std::string& message) const;

 private:
  template <typename T>
  T Read() {
    const size_t padding = Padding(sizeof(T));
    Need(padding + sizeof(T), PrimitiveName<T>());
    pos_ += padding;
    T value;
    std::memcpy(&value, data_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }

  // CDR pads to a multiple of `size` counted from the byte after the encapsulation header.
  size_t Padding(size_t size) const {
    if (serialization_ != Serialization::kCdr || size <= 1) return 0;
    const size_t misalignment = (pos_ - kCdrHeaderBytes) % size;
    return misalignment == 0 ? 0 : size - misalignment;
  }
  void Need(size_t bytes, const char* what) const {
    if (bytes > data_.size() - pos_) FailShort(bytes, what);
  }
  [[noreturn]] void FailShort(size_t bytes, const char* what) const;

  static constexpr size_t kCdrHeaderBytes = 4;
  std::string_view data_;
  Serialization serialization_;
  const MessageContext* context_;
  size_t pos_ = 0;
};

}  // namespace import
}  // namespace autocal
