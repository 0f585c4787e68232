#pragma once

// The format-specific readers behind io::ReadPointCloudFile. Private to src/io.

#include <string>

#include "autocal/io/point_cloud_file.h"
#include "autocal/lidar/point_cloud.h"

namespace autocal {
namespace io {
namespace internal {

// `bytes` is the whole file; `path` only names it in errors.
lidar::PointCloud ParsePly(const std::string& path, const std::string& bytes,
                           const PointCloudReadOptions& options);
lidar::PointCloud ParsePcd(const std::string& path, const std::string& bytes,
                           const PointCloudReadOptions& options);

}  // namespace internal
}  // namespace io
}  // namespace autocal
