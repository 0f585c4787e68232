#include "import/bag_reader.h"

#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "autocal/common/error.h"

namespace autocal {
namespace import {
namespace {

namespace fs = std::filesystem;

std::string Extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// The first bytes of a file, fewer when it is shorter.
std::string Head(const std::string& path, size_t bytes) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("cannot open '" + path + "': " + std::strerror(errno));
  std::string head(bytes, '\0');
  in.read(head.data(), static_cast<std::streamsize>(bytes));
  head.resize(static_cast<size_t>(in.gcount()));
  return head;
}

}  // namespace

SourceLocation MessageLocation(const std::string& path, const BagMessage& message) {
  if (message.row_id >= 0) return {path + " (row " + std::to_string(message.row_id) + ")"};
  return {path, 0, 0, static_cast<int64_t>(message.file_offset)};
}

std::vector<std::string> ReadWarnings(const BagReader& reader) {
  std::vector<std::string> warnings;
  if (!reader.IndexedTopics().has_value()) {
    warnings.push_back(reader.path() +
                       ": the bag has no (complete) index; it was read by a linear scan");
  }
  for (std::string& warning : reader.Warnings()) warnings.push_back(std::move(warning));
  return warnings;
}

std::unique_ptr<BagReader> OpenBag(const std::string& path) {
  std::error_code error;
  // A rosbag2 directory, with its metadata.yaml or, for part of a split recording, without.
  if (fs::is_directory(path, error)) return OpenRosbag2Directory(path);
  if (!fs::exists(path, error)) throw Error("input bag '" + path + "' does not exist");
  const std::string ext = Extension(path);
  if (ext == ".bag") return OpenRos1Bag(path);
  if (ext == ".mcap") return OpenMcap(path);
  if (ext == ".db3") return OpenRosbag2Sqlite(path);
  // Unknown extension: the magic bytes decide.
  const std::string head = Head(path, 16);
  if (head.rfind("#ROSBAG", 0) == 0) return OpenRos1Bag(path);
  if (head.rfind("\x89MCAP", 0) == 0) return OpenMcap(path);
  if (head.rfind("SQLite format 3", 0) == 0) return OpenRosbag2Sqlite(path);
  throw Error("'" + path +
              "' is neither a ROS 1 bag, an MCAP file, a rosbag2 SQLite file nor a rosbag2 "
              "directory (unknown extension and magic bytes)");
}

}  // namespace import
}  // namespace autocal
