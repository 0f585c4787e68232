#include "autocal/evaluation/trajectory_errors.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"
#include "estimation/keyframe_interpolation.h"

namespace autocal {
namespace evaluation {
namespace {

Eigen::Matrix3d YawRotation(double yaw_rad) {
  return Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

// The angle between the up directions that q_true and q_est give in the body (R^T z), from
// the cross and dot products so that small angles keep their precision.
double TiltRad(const Eigen::Quaterniond& q_true, const Eigen::Quaterniond& q_est) {
  const Eigen::Vector3d up_true = q_true.conjugate() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up_est = q_est.conjugate() * Eigen::Vector3d::UnitZ();
  return std::atan2(up_true.cross(up_est).norm(), up_true.dot(up_est));
}

}  // namespace

bool TruthAt(const io::Trajectory& truth, int64_t t_ns, int64_t max_gap_ns,
             io::TrajectorySample* sample, bool* exact) {
  const std::optional<estimation::internal::Bracket> at =
      estimation::internal::FindBracket(truth, t_ns, max_gap_ns);
  if (!at) return false;
  const io::TrajectorySample& before = truth[at->first];
  const io::TrajectorySample& after = truth[at->second];
  *exact = at->first == at->second;
  if (*exact) {
    *sample = after;
    return true;
  }
  const double s = at->s;
  sample->t_ns = t_ns;
  sample->T_W_I.p = (1.0 - s) * before.T_W_I.p + s * after.T_W_I.p;
  sample->T_W_I.q = before.T_W_I.q.slerp(s, after.T_W_I.q).normalized();
  sample->v_W_I = (1.0 - s) * before.v_W_I + s * after.v_W_I;
  return true;
}

Alignment4Dof AlignYawAndTranslation(const io::Trajectory& estimate, const io::Trajectory& truth,
                                     double min_horizontal_spread_m) {
  if (estimate.empty() || estimate.size() != truth.size()) {
    throw Error("4-DoF alignment needs matched pose pairs: got " + std::to_string(estimate.size()) +
                " estimated and " + std::to_string(truth.size()) + " true poses");
  }
  const double n = static_cast<double>(estimate.size());
  Eigen::Vector3d mean_estimate = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_truth = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < estimate.size(); ++i) {
    mean_estimate += estimate[i].T_W_I.p / n;
    mean_truth += truth[i].T_W_I.p / n;
  }
  // min over yaw of sum |Rz(yaw) a_i − b_i|² for centred a, b: the z parts do not depend on the
  // yaw, the x-y parts give yaw = atan2(S, C) (docs/evaluation.md, eq. 2).
  double c = 0.0;
  double s = 0.0;
  double spread_sq = 0.0;
  for (size_t i = 0; i < estimate.size(); ++i) {
    const Eigen::Vector3d a = estimate[i].T_W_I.p - mean_estimate;
    const Eigen::Vector3d b = truth[i].T_W_I.p - mean_truth;
    c += a.x() * b.x() + a.y() * b.y();
    s += a.x() * b.y() - a.y() * b.x();
    spread_sq += a.head<2>().squaredNorm() / n;
  }
  Alignment4Dof alignment;
  if (std::sqrt(spread_sq) >= min_horizontal_spread_m) {
    alignment.yaw_rad = std::atan2(s, c);
  } else {
    // Circular mean of the yaw of R_true R_est^T (eq. 3).
    double sin_sum = 0.0;
    double cos_sum = 0.0;
    for (size_t i = 0; i < estimate.size(); ++i) {
      const Eigen::Matrix3d R = truth[i].T_W_I.R() * estimate[i].T_W_I.R().transpose();
      const double yaw = std::atan2(R(1, 0), R(0, 0));
      sin_sum += std::sin(yaw);
      cos_sum += std::cos(yaw);
    }
    alignment.yaw_rad = std::atan2(sin_sum, cos_sum);
    alignment.yaw_from_orientation = true;
  }
  alignment.translation_m = mean_truth - YawRotation(alignment.yaw_rad) * mean_estimate;
  return alignment;
}

TrajectoryErrors CompareTrajectory(const io::Trajectory& estimate, const io::Trajectory& truth,
                                   const TrajectoryErrorOptions& options) {
  const int64_t max_gap_ns = SecondsToNs(options.max_interpolation_gap_s);
  TrajectoryErrors errors;
  io::Trajectory matched_estimate;
  io::Trajectory matched_truth;
  for (const io::TrajectorySample& pose : estimate) {
    io::TrajectorySample true_pose;
    bool exact = false;
    if (!TruthAt(truth, pose.t_ns, max_gap_ns, &true_pose, &exact)) {
      ++errors.unmatched_poses;
      continue;
    }
    matched_estimate.push_back(pose);
    matched_truth.push_back(true_pose);
    errors.exact_matches += exact ? 1 : 0;
  }
  errors.matched_poses = static_cast<int>(matched_estimate.size());
  if (matched_estimate.empty()) {
    throw Error("none of the " + std::to_string(estimate.size()) +
                " estimated poses falls within the ground truth's time span (" +
                std::to_string(truth.size()) + " true poses): are both on the IMU clock?");
  }
  errors.alignment =
      AlignYawAndTranslation(matched_estimate, matched_truth, options.min_horizontal_spread_m);
  const Eigen::Matrix3d R_yaw = YawRotation(errors.alignment.yaw_rad);
  const Eigen::Quaterniond q_yaw(R_yaw);
  double translation_sq = 0.0;
  double rotation_sq = 0.0;
  double tilt_sq = 0.0;
  for (size_t i = 0; i < matched_estimate.size(); ++i) {
    const geometry::Pose3d& est = matched_estimate[i].T_W_I;
    const geometry::Pose3d& tru = matched_truth[i].T_W_I;
    const double translation_m = (R_yaw * est.p + errors.alignment.translation_m - tru.p).norm();
    const double rotation_deg = kRadToDeg * geometry::AngularDistance(tru.q, q_yaw * est.q);
    const double tilt_deg = kRadToDeg * TiltRad(tru.q, est.q);
    tilt_sq += tilt_deg * tilt_deg;
    translation_sq += translation_m * translation_m;
    rotation_sq += rotation_deg * rotation_deg;
    errors.max_translation_error_m = std::max(errors.max_translation_error_m, translation_m);
    errors.max_rotation_error_deg = std::max(errors.max_rotation_error_deg, rotation_deg);
  }
  const double n = static_cast<double>(matched_estimate.size());
  errors.ate_translation_rmse_m = std::sqrt(translation_sq / n);
  errors.ate_rotation_rmse_deg = std::sqrt(rotation_sq / n);
  errors.tilt_rmse_deg = std::sqrt(tilt_sq / n);
  return errors;
}

}  // namespace evaluation
}  // namespace autocal
