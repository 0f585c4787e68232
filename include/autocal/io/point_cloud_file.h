#pragma once

// Point cloud files: PLY (ascii, binary_little_endian, binary_big_endian) and PCD (ascii,
// binary), chosen by the file extension (.ply / .pcd, case-insensitive).
//
// Recognised per-point properties (PLY) or fields (PCD):
//   x, y, z                      required, metres
//   intensity | scalar_intensity optional
//   t | time                     optional, seconds relative to the sweep stamp
// Every other property is skipped, PLY elements other than `vertex` (faces, ...) are
// ignored, any numeric type is accepted (PLY char/uchar/short/ushort/int/uint/float/double
// and their int8/.../float64 aliases; PCD TYPE F with SIZE 4/8, I and U with SIZE 1/2/4).
//
// Errors are autocal::ParseError: header problems name line and column, a truncated
// binary body names the byte offset where data ran out.

#include <string>

#include "autocal/lidar/point_cloud.h"

namespace autocal {
namespace io {

struct PointCloudReadOptions {
  // A point whose x, y, z, intensity or time is NaN or infinite is an error by default
  // (it would poison every sum it enters). Organized PCD clouds mark "no return" with NaN:
  // set this to drop such points instead.
  bool drop_non_finite_points = false;
};

lidar::PointCloud ReadPointCloudFile(const std::string& path,
                                     const PointCloudReadOptions& options = {});
// Whether ReadPointCloudFile reads `path` by its extension (.ply or .pcd, any case).
bool IsPointCloudFileName(const std::string& path);

// The two formats, for callers that know the format regardless of the extension.
lidar::PointCloud ReadPly(const std::string& path, const PointCloudReadOptions& options = {});
lidar::PointCloud ReadPcd(const std::string& path, const PointCloudReadOptions& options = {});

// Writes the sweep format of the dataset (datasets/README.md): binary little-endian PLY
// with float x, y, z, intensity, t. A cloud without intensity or time gets zeros in that
// column. Throws autocal::Error on a non-finite value or an I/O failure.
void WritePly(const std::string& path, const lidar::PointCloud& cloud);

}  // namespace io
}  // namespace autocal
