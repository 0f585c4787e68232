// autocal_register: aligns a source point cloud to a target (PLY or PCD) with ICP and prints
// T_target_source, inlier RMSE, iterations, time and the 6x6 covariance.
//
//   autocal_register --source=scan1.ply --target=scan0.ply [--method=point_to_plane]
//       [--loss=none|huber|cauchy] [--loss_scale_m=0.1] [--voxel_m=0.25]
//       [--max_correspondence_m=1.0] [--output=result.yaml]

#include <gflags/gflags.h>

#include <iostream>

#include "autocal/common/error.h"
#include "autocal/io/output_files.h"
#include "autocal/io/point_cloud_file.h"
#include "autocal/lidar/registration.h"
#include "tool_help.h"

DEFINE_string(source, "", "source cloud (.ply or .pcd), mapped into the target frame");
DEFINE_string(target, "", "target cloud (.ply or .pcd)");
DEFINE_string(method, "point_to_plane", "point_to_point | point_to_plane");
DEFINE_string(loss, "none", "robust loss: none | huber | cauchy");
DEFINE_double(loss_scale_m, 0.1, "robust loss scale (m)");
DEFINE_double(voxel_m, 0.25, "voxel size for downsampling both clouds (m), 0 = off");
DEFINE_double(max_correspondence_m, 1.0, "largest distance of a correspondence (m)");
DEFINE_string(output, "",
              "also write the result as YAML to this file (checked before the registration, "
              "replaced atomically)");

int main(int argc, char** argv) {
  gflags::SetUsageMessage(
      "autocal_register --source=A --target=B [--method=...] [--loss=...] [--output=FILE.yaml]");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_register")) return 0;
  gflags::ParseCommandLineFlags(&argc, &argv, true);
  try {
    if (argc > 1) throw autocal::Error(std::string("unexpected argument '") + argv[1] + "'");
    if (FLAGS_source.empty() || FLAGS_target.empty()) {
      throw autocal::Error("both --source and --target are required");
    }
    if (!FLAGS_output.empty()) autocal::io::CheckOutputFile(FLAGS_output);
    const autocal::lidar::RegistrationSetting setting = autocal::lidar::MakeRegistrationSetting(
        FLAGS_method, FLAGS_loss, FLAGS_loss_scale_m, FLAGS_voxel_m, FLAGS_max_correspondence_m);
    // Organized PCD clouds mark missing returns with NaN; they carry no geometry.
    autocal::io::PointCloudReadOptions read_options;
    read_options.drop_non_finite_points = true;
    const autocal::lidar::PointCloud source =
        autocal::io::ReadPointCloudFile(FLAGS_source, read_options);
    const autocal::lidar::PointCloud target =
        autocal::io::ReadPointCloudFile(FLAGS_target, read_options);
    const autocal::lidar::RegistrationResult result = autocal::lidar::RegisterPointClouds(
        source, target, autocal::geometry::Pose3d::Identity(), setting);
    std::cout << autocal::lidar::FormatRegistrationReport(result, setting);
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
