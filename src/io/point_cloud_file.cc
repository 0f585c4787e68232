#include "autocal/io/point_cloud_file.h"

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "io/point_cloud_formats.h"
#include "io/scalar_type.h"
#include "io/text_format.h"

namespace autocal {
namespace io {
namespace {

std::string LowerExtension(const std::string& path) {
  const size_t dot = path.find_last_of('.');
  const size_t slash = path.find_last_of('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string extension = path.substr(dot + 1);
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return extension;
}

void AppendLittleEndianFloat(float value, std::string* out) {
  unsigned char bytes[4];
  std::memcpy(bytes, &value, 4);
  if (!internal::HostIsLittleEndian()) {
    std::swap(bytes[0], bytes[3]);
    std::swap(bytes[1], bytes[2]);
  }
  out->append(reinterpret_cast<const char*>(bytes), 4);
}

}  // namespace

bool IsPointCloudFileName(const std::string& path) {
  const std::string extension = LowerExtension(path);
  return extension == "ply" || extension == "pcd";
}

lidar::PointCloud ReadPointCloudFile(const std::string& path,
                                     const PointCloudReadOptions& options) {
  const std::string extension = LowerExtension(path);
  if (extension == "ply") return ReadPly(path, options);
  if (extension == "pcd") return ReadPcd(path, options);
  throw Error("cannot read point cloud '" + path + "': unknown extension (expected .ply or .pcd)");
}

lidar::PointCloud ReadPly(const std::string& path, const PointCloudReadOptions& options) {
  return internal::ParsePly(path, internal::ReadFileBytes(path), options);
}

lidar::PointCloud ReadPcd(const std::string& path, const PointCloudReadOptions& options) {
  return internal::ParsePcd(path, internal::ReadFileBytes(path), options);
}

void WritePly(const std::string& path, const lidar::PointCloud& cloud) {
  const int64_t n = cloud.size();
  if (cloud.intensity.size() != 0 && cloud.intensity.size() != n) {
    throw Error("WritePly('" + path + "'): intensity has " +
                std::to_string(cloud.intensity.size()) + " values for " + std::to_string(n) +
                " points");
  }
  if (cloud.time_s.size() != 0 && cloud.time_s.size() != n) {
    throw Error("WritePly('" + path + "'): time_s has " + std::to_string(cloud.time_s.size()) +
                " values for " + std::to_string(n) + " points");
  }
  std::string out =
      "ply\n"
      "format binary_little_endian 1.0\n"
      "comment autocal LiDAR sweep: x y z [m] in frame L, intensity, t [s] after the sweep stamp\n"
      "element vertex " +
      std::to_string(n) +
      "\n"
      "property float x\n"
      "property float y\n"
      "property float z\n"
      "property float intensity\n"
      "property float t\n"
      "end_header\n";
  out.reserve(out.size() + static_cast<size_t>(n) * 20);
  for (int64_t i = 0; i < n; ++i) {
    const double values[5] = {cloud.points(0, i), cloud.points(1, i), cloud.points(2, i),
                              cloud.has_intensity() ? cloud.intensity[i] : 0.0,
                              cloud.has_time() ? cloud.time_s[i] : 0.0};
    for (double value : values) {
      // Stored as float: a finite double beyond its range would be written as infinity, which
      // the reader then refuses.
      if (!std::isfinite(value) || std::abs(value) > std::numeric_limits<float>::max()) {
        throw Error("WritePly('" + path + "'): point " + std::to_string(i) +
                    " has a value that is not a finite float (" + std::to_string(value) + ")");
      }
      AppendLittleEndianFloat(static_cast<float>(value), &out);
    }
  }
  internal::WriteFileText(path, out);
}

}  // namespace io
}  // namespace autocal
