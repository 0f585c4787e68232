#pragma once

// The record layer of ROS 1 bags (format 2.0, docs/import.md "ROS 1 bags"): the record kinds,
// little-endian fields, the "name=value" fields of a record header, and the file the reader
// holds open.

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace autocal {
namespace import {
namespace ros1 {

inline constexpr char kMagic[] = "#ROSBAG V2.0\n";
constexpr size_t kMagicBytes = 13;
// A chunk declaring more than this uncompressed is refused rather than allocated.
constexpr uint64_t kMaxChunkBytes = uint64_t{1} << 30;

enum Op : uint8_t {
  kMessageData = 0x02,
  kBagHeader = 0x03,
  kIndexData = 0x04,
  kChunk = 0x05,
  kChunkInfo = 0x06,
  kConnection = 0x07,
};

// The record kind's name for messages, e.g. "chunk record".
std::string OpName(int op);

inline uint32_t LoadU32(const char* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}
// A ROS 1 time: u32 sec, u32 nsec; nullopt when nsec is not below 1e9 (not a time: taken as
// it is, it would move the stamp by up to 4.3 s).
inline std::optional<int64_t> LoadTimeNs(const char* p) {
  const uint32_t nsec = LoadU32(p + 4);
  if (nsec >= 1000000000u) return std::nullopt;
  return int64_t{LoadU32(p)} * 1000000000 + nsec;
}

// The "name=value" fields of a record header (or of a connection record's data).
class HeaderFields {
 public:
  // `bytes` must outlive this. On a malformed field returns false and sets *why.
  bool Parse(std::string_view bytes, std::string* why);

  const std::string_view* Find(std::string_view name) const {
    for (const auto& field : fields_) {
      if (field.first == name) return &field.second;
    }
    return nullptr;
  }

 private:
  std::vector<std::pair<std::string_view, std::string_view>> fields_;
};

// Owns an open file descriptor and closes it, also when the reader's constructor throws
// (a member is destroyed then, the reader's own destructor does not run).
class FileDescriptor {
 public:
  FileDescriptor() = default;
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  ~FileDescriptor();
  // Opens `path` read-only; get() is negative when that failed (errno says why).
  void Open(const std::string& path);
  int get() const { return fd_; }

 private:
  int fd_ = -1;
};

}  // namespace ros1
}  // namespace import
}  // namespace autocal
