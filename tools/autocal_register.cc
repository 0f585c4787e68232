// autocal_register: aligns a source point cloud to a target (PLY or PCD) with ICP and prints
// T_target_source, inlier RMSE, iterations, time and the 6x6 covariance. Exit status: 0
// converged, 1 bad input or a failed alignment, 2 not converged within --max_iterations (the
// report is printed, no --output file is written). See docs/lidar.md.

#include <gflags/gflags.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include "autocal/common/error.h"
#include "autocal/io/output_files.h"
#include "autocal/io/point_cloud_file.h"
#include "autocal/lidar/registration.h"
#include "tool_checks.h"
#include "tool_help.h"

DEFINE_string(source, "", "source cloud (.ply or .pcd), mapped into the target frame");
DEFINE_string(target, "", "target cloud (.ply or .pcd)");
DEFINE_string(method, "point_to_plane", "point_to_point | point_to_plane | gicp");
DEFINE_string(loss, "none", "robust loss: none | huber | cauchy");
DEFINE_double(loss_scale_m, 0.1, "robust loss scale (m)");
DEFINE_double(voxel_m, 0.25, "voxel size for downsampling both clouds (m), 0 = off");
DEFINE_double(max_correspondence_m, 1.0, "largest distance of a correspondence (m)");
DEFINE_string(init, "",
              "initial T_target_source: x,y,z,roll,pitch,yaw (m, deg; R = Rz Ry Rx) or a file "
              "holding a 4x4 matrix (default: identity)");
DEFINE_int32(max_iterations, 30, "ICP iterations at most (correspondence search + solve)");
DEFINE_int32(num_threads, 1, "threads for the normals, the correspondences and the solve");
DEFINE_string(output, "",
              "also write the result as YAML to this file (checked before the registration, "
              "replaced atomically; not one of the input files)");

namespace {

constexpr int kExitNotConverged = 2;

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in && !in.eof()) throw autocal::Error(path + ": cannot be read");
  return text.str();
}

// --init as a pose: the 6-number form, or a file's 4x4 matrix.
autocal::geometry::Pose3d InitialGuess() {
  if (FLAGS_init.empty()) return autocal::geometry::Pose3d::Identity();
  if (FLAGS_init.find(',') == std::string::npos && std::filesystem::is_regular_file(FLAGS_init)) {
    return autocal::lidar::ParsePoseGuess(ReadText(FLAGS_init), FLAGS_init);
  }
  return autocal::lidar::ParsePoseGuess(FLAGS_init, "--init");
}

autocal::lidar::RegistrationOptions OptionsFromFlags() {
  autocal::lidar::RegistrationOptions setting = autocal::lidar::MakeRegistrationOptions(
      FLAGS_method, FLAGS_loss, FLAGS_loss_scale_m, FLAGS_voxel_m, FLAGS_max_correspondence_m);
  if (FLAGS_max_iterations < 1) throw autocal::Error("--max_iterations must be at least 1");
  if (FLAGS_num_threads < 1) throw autocal::Error("--num_threads must be at least 1");
  setting.icp.convergence.max_iterations = FLAGS_max_iterations;
  setting.icp.num_threads = FLAGS_num_threads;
  return setting;
}

}  // namespace

int main(int argc, char** argv) {
  gflags::SetUsageMessage(
      "autocal_register --source=A --target=B [--init=x,y,z,roll,pitch,yaw|FILE] [--method=...] "
      "[--loss=...] [--output=FILE.yaml]\n"
      "Exit status: 0 converged, 1 bad input or failed alignment, 2 not converged.");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_register")) return 0;
  gflags::ParseCommandLineFlags(&argc, &argv, true);
  try {
    if (argc > 1) throw autocal::Error(std::string("unexpected argument '") + argv[1] + "'");
    if (FLAGS_source.empty() || FLAGS_target.empty()) {
      throw autocal::Error("both --source and --target are required");
    }
    if (!FLAGS_output.empty()) {
      const bool init_is_file = FLAGS_init.find(',') == std::string::npos;
      autocal::tools::CheckOutputFileIsNoInput(FLAGS_output, "--output",
                                               {{"--source", FLAGS_source},
                                                {"--target", FLAGS_target},
                                                {"--init", init_is_file ? FLAGS_init : ""}});
      autocal::io::CheckOutputFile(FLAGS_output);
    }
    const autocal::lidar::RegistrationOptions setting = OptionsFromFlags();
    const autocal::geometry::Pose3d guess = InitialGuess();
    // Organized PCD clouds mark missing returns with NaN; they carry no geometry.
    autocal::io::PointCloudReadOptions read_options;
    read_options.drop_non_finite_points = true;
    const autocal::lidar::PointCloud source =
        autocal::io::ReadPointCloudFile(FLAGS_source, read_options);
    const autocal::lidar::PointCloud target =
        autocal::io::ReadPointCloudFile(FLAGS_target, read_options);
    const autocal::lidar::RegistrationResult result =
        autocal::lidar::RegisterPointClouds(source, target, guess, setting);
    std::cout << autocal::lidar::FormatRegistrationReport(result, setting);
    if (!result.icp.converged) {
      std::cerr << "autocal_register: not converged within " << FLAGS_max_iterations
                << " iterations; no result file written\n";
      return kExitNotConverged;
    }
    if (!FLAGS_output.empty()) {
      autocal::io::WriteFileAtomically(FLAGS_output,
                                       autocal::lidar::FormatRegistrationYaml(result, setting));
    }
  } catch (const autocal::Error& e) {
    std::cerr << "autocal_register: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
