// autocal_export: writes a calibration result in the file format of another stack (Kalibr,
// FAST-LIO, LIO-SAM, Autoware, URDF, ROS 2 static transforms). See docs/export.md.

#include <gflags/gflags.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <string>

#include "autocal/common/error.h"
#include "autocal/io/calibration_export.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/output_files.h"
#include "tool_checks.h"
#include "tool_help.h"

DEFINE_string(result, "", "result directory (its calibration.yaml) or a calibration.yaml file");
DEFINE_string(format, "", "kalibr, fast_lio, lio_sam, autoware, urdf or ros2_static_tf");
DEFINE_string(output, "-",
              "file to write (replaced whole; not the result's calibration.yaml), or - for the "
              "standard output");
DEFINE_string(vehicle_frame, "base_link", "name of the vehicle frame");
DEFINE_string(imu_frame, "imu_link", "name of the IMU frame");
DEFINE_string(lidar_frame, "lidar_link", "name of the LiDAR frame");
DEFINE_string(gnss_frame, "gnss_link", "name of the GNSS antenna frame");
DEFINE_string(base_link_below_axle_m, "",
              "how far the vehicle frame lies below the rear-axle centre, m (empty: the mean "
              "calibrated rear wheel radius for autoware, else 0)");

namespace {

std::string CalibrationPath(const std::string& result) {
  const std::filesystem::path path(result);
  return std::filesystem::is_directory(path) ? (path / "calibration.yaml").string() : result;
}

autocal::io::ExportOptions Options() {
  autocal::io::ExportOptions options;
  options.vehicle_frame = FLAGS_vehicle_frame;
  options.imu_frame = FLAGS_imu_frame;
  options.lidar_frame = FLAGS_lidar_frame;
  options.gnss_frame = FLAGS_gnss_frame;
  if (!FLAGS_base_link_below_axle_m.empty()) {
    const std::string& text = FLAGS_base_link_below_axle_m;
    char* end = nullptr;
    const double value = std::strtod(text.c_str(), &end);
    if (end != text.c_str() + text.size() || !std::isfinite(value)) {
      throw autocal::Error("--base_link_below_axle_m must be a number, got '" + text + "'");
    }
    options.base_link_below_axle_m = value;
  }
  return options;
}

}  // namespace

int main(int argc, char** argv) {
  gflags::SetUsageMessage(
      "writes a calibration result in another stack's format\n"
      "  autocal_export --result=DIR --format=kalibr|fast_lio|lio_sam|autoware|urdf|ros2_static_tf "
      "[--output=FILE]\n"
      "Frames, time-offset signs and sources of each format: docs/export.md. Exit status 0, or\n"
      "1 with a message (bad flags, unreadable result, a format needing a block the result\n"
      "did not estimate).");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_export")) return 0;
  gflags::ParseCommandLineFlags(&argc, &argv, true);
  try {
    if (argc > 1) throw autocal::Error(std::string("unexpected argument '") + argv[1] + "'");
    if (FLAGS_result.empty()) throw autocal::Error("--result is required");
    if (FLAGS_format.empty()) throw autocal::Error("--format is required");
    const autocal::io::ExportFormat format = autocal::io::ParseExportFormat(FLAGS_format);
    const std::string input = CalibrationPath(FLAGS_result);
    if (FLAGS_output != "-") {
      autocal::tools::CheckOutputFileIsNoInput(FLAGS_output, "--output", {{"--result", input}});
      autocal::io::CheckOutputFile(FLAGS_output);
    }
    const autocal::io::CalibrationFile result = autocal::io::ReadCalibrationYaml(input);
    const std::string text = autocal::io::ExportCalibration(result, format, Options());
    if (FLAGS_output == "-") {
      std::cout << text;
    } else {
      autocal::io::WriteFileAtomically(FLAGS_output, text);
    }
  } catch (const std::exception& e) {
    std::cerr << "autocal_export: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
