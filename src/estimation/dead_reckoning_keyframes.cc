#include "autocal/estimation/dead_reckoning_keyframes.h"

#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/factors/prior_factors.h"
#include "autocal/sensors/imu_preintegration.h"
#include "estimation/keyframe_interpolation.h"

namespace autocal {
namespace estimation {

void PlaceKeyframesByDeadReckoning(std::vector<Keyframe>* keyframes, const sensors::ImuSamples& imu,
                                   const ScalarSeries& speed_m_s, const Eigen::Quaterniond& q_I_V,
                                   const Eigen::Vector3d& p_I_V) {
  std::vector<Keyframe>& kfs = *keyframes;
  if (kfs.size() < 2) throw Error("PlaceKeyframesByDeadReckoning: need at least two keyframes");
  if (imu.empty() || imu.front().t_ns > kfs.front().t_ns || imu.back().t_ns < kfs.back().t_ns) {
    throw Error("PlaceKeyframesByDeadReckoning: the IMU samples do not cover the keyframes");
  }
  if (speed_m_s.empty()) throw Error("PlaceKeyframesByDeadReckoning: no wheel speed");
  const Eigen::Quaterniond q_V_I = q_I_V.conjugate();
  const std::vector<double> yaw_rad =
      internal::GyroYawAtKeyframes(imu, kfs, q_I_V * Eigen::Vector3d::UnitZ());
  for (size_t k = 0; k < kfs.size(); ++k) {
    Keyframe& kf = kfs[k];
    const Eigen::Quaterniond q_W_V(Eigen::AngleAxisd(yaw_rad[k], Eigen::Vector3d::UnitZ()));
    kf.q_W_I = (q_W_V * q_V_I).normalized();
    // The IMU moves with the rear axle plus the turn about it: v_I = v_V + w x p_V_I, with
    // p_V_I = -p_I_V seen in I.
    kf.v_W_I = q_W_V * Eigen::Vector3d(InterpolateSeries(speed_m_s, kf.t_ns), 0.0, 0.0) -
               kf.q_W_I * sensors::InterpolateImu(imu, kf.t_ns).gyro_rad_s.cross(p_I_V);
    kf.p_W_I =
        k == 0 ? Eigen::Vector3d::Zero()
               : Eigen::Vector3d(kfs[k - 1].p_W_I + 0.5 * (kfs[k - 1].v_W_I + kf.v_W_I) *
                                                        SecondsBetween(kfs[k - 1].t_ns, kf.t_ns));
    kf.b_g.setZero();
    kf.b_a.setZero();
  }
}

void AddDeadReckoningGauge(ceres::Problem* problem, Keyframe* first, double position_sigma_m,
                           double yaw_sigma_rad) {
  if (!(position_sigma_m > 0.0) || !(yaw_sigma_rad > 0.0)) {
    throw Error("AddDeadReckoningGauge: the sigmas must be positive");
  }
  // The right tangent of q_W_I is in I: a turn about the world's vertical is the direction
  // R_W_I^T z there, the one row of the rotation prior.
  Eigen::Matrix3d yaw_row = Eigen::Matrix3d::Zero();
  yaw_row.row(0) =
      (first->q_W_I.conjugate() * Eigen::Vector3d::UnitZ()).transpose() / yaw_sigma_rad;
  problem->AddResidualBlock(new factors::QuaternionPriorFactor(first->q_W_I, yaw_row), nullptr,
                            first->q_W_I.coeffs().data());
  problem->AddResidualBlock(
      new factors::VectorPriorFactor(first->p_W_I, Eigen::Matrix3d::Identity() / position_sigma_m),
      nullptr, first->p_W_I.data());
}

}  // namespace estimation
}  // namespace autocal
