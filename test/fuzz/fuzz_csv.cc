// libFuzzer target: the dataset CSV readers (imu, wheel, gnss, lidar, ground-truth
// trajectory, wheel speeds, odometry). The first byte picks the reader, the rest is the file.

#include <cstddef>
#include <cstdint>
#include <string>

#include "autocal/io/csv_files.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace autocal;
  if (size == 0) return 0;
  const std::string& path = fuzz::ScratchPath(".csv");
  fuzz::WriteScratch(path, data + 1, size - 1);
  fuzz::ExpectParsedOrRefused([&] {
    switch (data[0] % 7) {
      case 0:
        io::ReadImuCsv(path);
        break;
      case 1:
        io::ReadWheelCsv(path);
        break;
      case 2:
        io::ReadGnssCsv(path);
        break;
      case 3:
        io::ReadLidarCsv(path);
        break;
      case 4:
        io::ReadTrajectoryCsv(path);
        break;
      case 5:
        io::ReadWheelSpeedCsv(path);
        break;
      default:
        io::ReadOdometryCsv(path);
        break;
    }
  });
  return 0;
}
