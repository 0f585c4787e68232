#include "autocal/lidar/registration.h"

#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <sstream>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/geometry/roll_pitch_yaw.h"
#include "autocal/lidar/voxel_grid.h"

namespace autocal {
namespace lidar {
namespace {

Eigen::Matrix3Xd Downsampled(const PointCloud& cloud, double voxel_m) {
  if (voxel_m > 0.0) return VoxelDownsample(cloud, voxel_m).points;
  CheckPointCloud(cloud, "registration input");
  return cloud.points;
}

void WriteMatrixRows(std::ostream& out, const Eigen::MatrixXd& m, const std::string& indent) {
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    out << indent << "- [";
    for (Eigen::Index c = 0; c < m.cols(); ++c) out << (c ? ", " : "") << m(r, c);
    out << "]\n";
  }
}

}  // namespace

RegistrationOptions MakeRegistrationOptions(const std::string& method, const std::string& loss,
                                            double loss_scale_m, double voxel_m,
                                            double max_correspondence_m) {
  RegistrationOptions setting;
  setting.icp.method = ParseIcpMethod(method);
  setting.icp.robust.loss = factors::ParseRobustLoss(loss);
  if (!(loss_scale_m > 0.0) || !std::isfinite(loss_scale_m)) {
    throw Error("loss_scale_m must be a positive number of metres, got " +
                std::to_string(loss_scale_m));
  }
  setting.icp.robust.scale_m = loss_scale_m;
  if (!(voxel_m >= 0.0) || !std::isfinite(voxel_m)) {
    throw Error("voxel_m must be >= 0 (0 disables downsampling), got " + std::to_string(voxel_m));
  }
  setting.voxel_m = voxel_m;
  if (!(max_correspondence_m > 0.0) || !std::isfinite(max_correspondence_m)) {
    throw Error("max_correspondence_m must be a positive number of metres, got " +
                std::to_string(max_correspondence_m));
  }
  setting.icp.max_correspondence_m = max_correspondence_m;
  return setting;
}

namespace {

// The numbers of `text`, separated by spaces, commas, brackets or line breaks.
std::vector<double> NumbersIn(const std::string& text, const std::string& what) {
  std::vector<double> numbers;
  std::string token;
  int line = 1, column = 0, token_line = 1, token_column = 1;
  const auto flush = [&]() {
    if (token.empty()) return;
    char* end = nullptr;
    const double value = std::strtod(token.c_str(), &end);
    if (end != token.c_str() + token.size() || !std::isfinite(value)) {
      throw Error(what + ":" + std::to_string(token_line) + ":" + std::to_string(token_column) +
                  ": '" + token + "' (number " + std::to_string(numbers.size() + 1) +
                  ") is not a finite number");
    }
    numbers.push_back(value);
    token.clear();
  };
  for (const char c : text) {
    ++column;
    if (std::isspace(static_cast<unsigned char>(c)) || c == ',' || c == '[' || c == ']') {
      flush();
      if (c == '\n') {
        ++line;
        column = 0;
      }
    } else {
      if (token.empty()) {
        token_line = line;
        token_column = column;
      }
      token += c;
    }
  }
  flush();
  return numbers;
}

}  // namespace

geometry::Pose3d ParsePoseGuess(const std::string& text, const std::string& what) {
  const std::vector<double> v = NumbersIn(text, what);
  if (v.size() == 6) {
    return geometry::Pose3d(
        geometry::FromRollPitchYaw(v[3] * kDegToRad, v[4] * kDegToRad, v[5] * kDegToRad),
        Eigen::Vector3d(v[0], v[1], v[2]));
  }
  if (v.size() != 16) {
    throw Error(what +
                ": expected 6 numbers (x,y,z in m, roll,pitch,yaw in deg) or 16 (a 4x4 "
                "matrix), found " +
                std::to_string(v.size()));
  }
  return PoseGuessFromMatrix(
      Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(v.data()), what);
}

geometry::Pose3d PoseGuessFromMatrix(const Eigen::Matrix4d& m, const std::string& what) {
  if (!m.allFinite()) throw Error(what + ": the 4x4 matrix holds a non-finite number");
  if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
    throw Error(what + ": the last row of the 4x4 matrix must be 0 0 0 1");
  }
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-4 ||
      R.determinant() < 0.0) {
    throw Error(what +
                ": the 3x3 block of the matrix is not a rotation (orthonormal to 1e-4, "
                "determinant +1)");
  }
  return geometry::Pose3d::FromMatrix(m);
}

RegistrationResult RegisterPointClouds(const PointCloud& source, const PointCloud& target,
                                       const geometry::Pose3d& T_target_source_guess,
                                       const RegistrationOptions& setting) {
  if (source.empty()) throw Error("registration: the source cloud is empty");
  if (target.empty()) throw Error("registration: the target cloud is empty");
  if (setting.voxel_m < 0.0) {
    throw Error("registration: voxel size must be >= 0, got " + std::to_string(setting.voxel_m));
  }
  const auto start = std::chrono::steady_clock::now();
  const Eigen::Matrix3Xd source_points = Downsampled(source, setting.voxel_m);
  const bool with_normals = setting.icp.method != IcpMethod::kPointToPoint;
  const IcpTarget prepared(Downsampled(target, setting.voxel_m),
                           with_normals ? TargetNormals::kAll : TargetNormals::kNone,
                           setting.target_normals, setting.icp.num_threads);
  RegistrationResult result;
  result.icp = AlignIcp(source_points, prepared, T_target_source_guess, setting.icp);
  result.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.source_points = source_points.cols();
  result.target_points = prepared.points().cols();
  return result;
}

std::string FormatRegistrationReport(const RegistrationResult& result,
                                     const RegistrationOptions& setting) {
  const IcpResult& icp = result.icp;
  std::ostringstream out;
  out << std::setprecision(9);
  const Eigen::IOFormat matrix_format(Eigen::FullPrecision, 0, " ", "\n", "  ", "");
  out << "method: " << IcpMethodName(setting.icp.method)
      << "  loss: " << factors::RobustLossName(setting.icp.robust.loss);
  if (setting.icp.robust.loss != factors::RobustLoss::kNone)
    out << " (scale " << setting.icp.robust.scale_m << " m)";
  out << "  voxel: " << setting.voxel_m
      << " m  max correspondence: " << setting.icp.max_correspondence_m << " m\n";
  out << "points after downsampling: source " << result.source_points << ", target "
      << result.target_points << "\n";
  out << "T_target_source:\n" << icp.T_target_source.Matrix().format(matrix_format) << "\n";
  out << "inlier RMSE: " << icp.inlier_rmse_m << " m over " << icp.num_correspondences
      << " correspondences (fitness " << icp.fitness << ")\n";
  out << "iterations: " << icp.iterations << (icp.converged ? " (converged)" : " (not converged)")
      << "\n";
  out << "time: " << 1e3 * result.time_s << " ms\n";
  out << "covariance of [rho; phi] (left perturbation in the target frame, m and rad; "
         "residual sigma "
      << icp.residual_sigma_m << " m):\n"
      << icp.covariance.format(matrix_format) << "\n";
  return out.str();
}

std::string FormatRegistrationYaml(const RegistrationResult& result,
                                   const RegistrationOptions& setting) {
  const IcpResult& icp = result.icp;
  const Eigen::Quaterniond& q = icp.T_target_source.q;
  const Eigen::Vector3d& p = icp.T_target_source.p;
  std::ostringstream out;
  out << std::setprecision(12);
  out << "method: " << IcpMethodName(setting.icp.method) << "\n";
  out << "loss: " << factors::RobustLossName(setting.icp.robust.loss) << "\n";
  out << "loss_scale_m: " << setting.icp.robust.scale_m << "\n";
  out << "voxel_m: " << setting.voxel_m << "\n";
  out << "max_correspondence_m: " << setting.icp.max_correspondence_m << "\n";
  out << "T_target_source:\n";
  WriteMatrixRows(out, icp.T_target_source.Matrix(), "  ");
  out << "q_xyzw: [" << q.x() << ", " << q.y() << ", " << q.z() << ", " << q.w() << "]\n";
  out << "p_m: [" << p.x() << ", " << p.y() << ", " << p.z() << "]\n";
  out << "# Cov of the left perturbation [rho (m); phi (rad)] in the target frame.\n";
  out << "covariance:\n";
  WriteMatrixRows(out, icp.covariance, "  ");
  out << "residual_sigma_m: " << icp.residual_sigma_m << "\n";
  out << "inlier_rmse_m: " << icp.inlier_rmse_m << "\n";
  out << "num_correspondences: " << icp.num_correspondences << "\n";
  out << "fitness: " << icp.fitness << "\n";
  out << "iterations: " << icp.iterations << "\n";
  out << "converged: " << (icp.converged ? "true" : "false") << "\n";
  out << "source_points: " << result.source_points << "\n";
  out << "target_points: " << result.target_points << "\n";
  out << "time_s: " << result.time_s << "\n";
  return out.str();
}

}  // namespace lidar
}  // namespace autocal
