#pragma once

// The axis the vehicle turns about, measured from the body rates the wheel rows take
// (docs/keyframe_factors.md, Eq. K13c): the yaw-rate rows read the body rate about it, so that
// a tilt error of the mount (q_I_V) does not lengthen the track.

#include <Eigen/Core>
#include <optional>

namespace autocal {
namespace estimation {
namespace internal {

// The principal axis of the spread of n body-rate readings (`spread`: their covariance, sum of
// (w - mean)(w - mean)^T over n), oriented along up_I, when its standard error towards the
// second axis, sqrt(l1 l2 / (n (l1 - l2)^2)) for an eigenvector of a sample covariance, is
// below max_error_rad; nullopt for fewer than three readings, a drive with too few turns, or a
// principal axis that is not the spread's axis nearest up_I (pitching on a straight road).
std::optional<Eigen::Vector3d> PrincipalTurningAxis(int n, const Eigen::Matrix3d& spread,
                                                    const Eigen::Vector3d& up_I,
                                                    double max_error_rad);

// The readings' running mean and spread (Welford's update), for an estimator that takes them
// one at a time.
class TurningRateSpread {
 public:
  void Add(const Eigen::Vector3d& rate_rad_s);
  int count() const { return n_; }
  // PrincipalTurningAxis of the readings added so far.
  std::optional<Eigen::Vector3d> Axis(const Eigen::Vector3d& up_I, double max_error_rad) const;

 private:
  int n_ = 0;
  Eigen::Vector3d mean_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_sq_ = Eigen::Matrix3d::Zero();  // sum of (w - mean)(w - mean)^T
};

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
