#pragma once

// Column names and row formatting of the dataset CSV files, shared by the one-shot
// writers (csv_files.cc) and the incremental DatasetWriter. Private to src/io.

#include <string>
#include <vector>

#include "autocal/io/dataset.h"

namespace autocal {
namespace io {
namespace internal {

const std::vector<std::string>& ImuColumns();
const std::vector<std::string>& WheelColumns();
const std::vector<std::string>& GnssColumns();
const std::vector<std::string>& LidarColumns();
const std::vector<std::string>& TrajectoryColumns();
const std::vector<std::string>& ImuBiasColumns();

// "a,b,c\n"
std::string HeaderLine(const std::vector<std::string>& columns);

// Throws autocal::Error when `file` cannot name a sweep inside lidar/ (empty, absolute,
// '..', a comma or a line break).
void CheckSweepFileName(const std::string& file);
std::string LidarRow(const LidarSweepRef& sweep);

}  // namespace internal
}  // namespace io
}  // namespace autocal
