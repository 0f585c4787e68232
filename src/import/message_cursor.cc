#include "import/message_cursor.h"

#include <algorithm>

#include "autocal/common/error.h"

namespace autocal {
namespace import {

MessageCursor::MessageCursor(std::string_view data, Serialization serialization,
                             const MessageContext* context)
    : data_(data), serialization_(serialization), context_(context) {
  if (serialization_ != Serialization::kCdr) return;
  Need(kCdrHeaderBytes, "the CDR encapsulation header");
  const auto b0 = static_cast<uint8_t>(data_[0]);
  const auto b1 = static_cast<uint8_t>(data_[1]);
  if (b0 != 0x00 || b1 != 0x01) {
    Fail("CDR encapsulation header is " + std::to_string(b0) + " " + std::to_string(b1) +
         ", expected 0 1 (little-endian plain CDR); big-endian and parameter-list CDR are "
         "not supported");
  }
  pos_ = kCdrHeaderBytes;
}

std::string_view MessageCursor::String() {
  const uint32_t length = U32();
  Need(length, "the string's bytes");
  std::string_view text = data_.substr(pos_, length);
  pos_ += length;
  if (serialization_ == Serialization::kCdr) {
    // CDR counts the terminating NUL; an empty CDR string still has it (count 1).
    if (length == 0 || text.back() != '\0') {
      pos_ -= length;
      Fail("CDR string of " + std::to_string(length) + " bytes does not end with a NUL");
    }
    text.remove_suffix(1);
  }
  return text;
}

uint32_t MessageCursor::SequenceCount(size_t min_element_bytes) {
  const uint32_t count = U32();
  if (min_element_bytes > 0 && count > remaining() / min_element_bytes) {
    pos_ -= 4;
    Fail("sequence of " + std::to_string(count) + " elements of at least " +
         std::to_string(min_element_bytes) + " bytes does not fit in the " +
         std::to_string(remaining() - 4) + " bytes left");
  }
  return count;
}

std::string_view MessageCursor::Bytes(size_t count) {
  Need(count, "a byte array");
  std::string_view bytes = data_.substr(pos_, count);
  pos_ += count;
  return bytes;
}

void MessageCursor::SkipArray(size_t count, size_t element_bytes) {
  if (count == 0) return;
  const size_t padding = Padding(element_bytes);
  if (element_bytes != 0 &&
      count > (remaining() - std::min(padding, remaining())) / element_bytes) {
    FailShort(padding + count * element_bytes, "a fixed-size array");
  }
  pos_ += padding + count * element_bytes;
}

int64_t MessageCursor::Header(std::string* frame_id) {
  int64_t sec = 0;
  uint32_t nsec = 0;
  if (serialization_ == Serialization::kRos1) {
    U32();  // seq
    sec = U32();
    nsec = U32();
  } else {
    sec = I32();
    nsec = U32();
  }
  if (nsec >= 1000000000u) {
    pos_ -= 4;
    Fail("header stamp has " + std::to_string(nsec) + " nanoseconds, expected < 1e9");
  }
  const std::string_view frame = String();
  if (frame_id != nullptr) frame_id->assign(frame.data(), frame.size());
  return sec * 1000000000 + nsec;
}

void MessageCursor::Fail(const std::string& message) const {
  SourceLocation location;
  std::string what = "message";
  if (context_ != nullptr) {
    location.file = context_->bag_path;
    location.byte_offset = static_cast<int64_t>(context_->record_offset);
    what = context_->type + " message" +
           (context_->topic.empty() ? std::string() : " on " + context_->topic);
  }
  throw ParseError(location, what + ", byte " + std::to_string(pos_) + " of " +
                                 std::to_string(data_.size()) + ": " + message);
}

void MessageCursor::FailShort(size_t bytes, const char* what) const {
  Fail(std::string("message too short for its type: ") + what + " needs " + std::to_string(bytes) +
       " bytes, " + std::to_string(data_.size() - pos_) + " left");
}

}  // namespace import
}  // namespace autocal
