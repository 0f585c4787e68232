#pragma once

// Initialization without a hand-measured guess (docs/estimation.md, "Initialization"):
//   1. gravity direction and gyro bias from a still start (DetectStillStart);
//   2. the LiDAR-IMU time offset by cross-correlating angular-rate magnitudes, which do not
//      depend on the unknown rotation between the sensors (EstimateTimeOffset);
//   3. q_I_L by hand-eye rotation alignment of IMU and LiDAR relative rotations
//      (SolveHandEyeRotation);
//   4. p_I_L by hand-eye translation least squares where the motion excites it
//      (SolveHandEyeTranslation).
// Each step reports when the motion is too poor to determine its result.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "autocal/common/units.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace estimation {

// ---- 1. Still start.

struct StillStartOptions {
  double min_duration_s = 1.0;       // shortest still period accepted
  double max_gyro_std_rad_s = 0.01;  // per-axis standard deviation while still
  double max_accel_std_m_s2 = 0.05;  // per-axis standard deviation while still
  // Mean rate (norm, bias included) above which a block is turning, however steadily: a
  // constant-rate turn has a small standard deviation too. Gyro biases are far below this.
  double max_gyro_mean_rad_s = 0.05;
  double max_search_s = 30.0;  // look for the still period in the first seconds
};

struct StillStart {
  bool found = false;
  std::string reason;  // why not, when !found
  int64_t t_begin_ns = 0;
  int64_t t_end_ns = 0;
  Eigen::Vector3d gyro_bias_rad_s = Eigen::Vector3d::Zero();
  // Roll and pitch of the IMU from the measured specific force (yaw set to 0).
  Eigen::Quaterniond q_W_I = Eigen::Quaterniond::Identity();
  double gravity_m_s2 = 0.0;  // measured magnitude of the specific force
};

// Finds the first still period of at least min_duration_s that starts within the first
// max_search_s seconds (blocks turning at a steady rate do not count as still).
StillStart DetectStillStart(const sensors::ImuSamples& imu, const StillStartOptions& options = {});

// ---- 2. Time offset.

// A relative rotation between two instants of one sensor's clock: R_a_b maps vectors from
// the frame at t1 to the frame at t0.
struct RelativeRotation {
  int64_t t0_ns = 0;
  int64_t t1_ns = 0;
  Eigen::Quaterniond q_0_1 = Eigen::Quaterniond::Identity();
};

// The widest time-offset search accepted: clocks further apart than a minute are not
// synchronized at all, and their stamps need aligning before a correlation can help.
constexpr double kMaxTimeOffsetSearchRangeS = 60.0;

// EstimateTimeOffset throws autocal::Error unless 0 < search_range_s <=
// kMaxTimeOffsetSearchRangeS and 0 < step_s <= search_range_s.
struct TimeOffsetOptions {
  double search_range_s = 0.2;  // offsets in [-range, +range] are tried
  // Grid step before sub-step refinement; the grid's last candidate either side is the last
  // whole step inside the range.
  double step_s = 0.001;
  // Below this Pearson correlation at the peak the motion is too poor (too little rate
  // variation) to trust the estimate.
  double min_peak_correlation = 0.8;
};

struct TimeOffsetEstimate {
  bool reliable = false;
  std::string reason;
  double offset_s = 0.0;  // t_imu = t_lidar + offset_s
  double peak_correlation = 0.0;
  std::vector<double> candidate_offsets_s;  // the correlation curve, for reports
  std::vector<double> correlation;
};

// Correlates |mean angular rate| of the LiDAR's relative rotations (stamped on the LiDAR
// clock) with the gyro's (bias removed) over the same intervals shifted by each candidate
// offset; the peak, refined by a parabola through its neighbours, is the offset.
TimeOffsetEstimate EstimateTimeOffset(const std::vector<RelativeRotation>& lidar_rotations,
                                      const sensors::ImuSamples& imu,
                                      const Eigen::Vector3d& gyro_bias_rad_s,
                                      const TimeOffsetOptions& options = {});

// The IMU's rotation R_I(t0)_I(t1) from gyro integration (bias removed, each step at its mean
// rate), t in IMU time; costs the samples in [t0, t1]. Throws autocal::Error when the samples
// do not cover [t0, t1] or t1 < t0.
Eigen::Quaterniond IntegrateGyro(const sensors::ImuSamples& imu, const Eigen::Vector3d& gyro_bias,
                                 int64_t t0_ns, int64_t t1_ns);

// ---- 3. Hand-eye rotation.

// The rotation is determined when three tests pass (docs/estimation.md, "Hand-eye
// rotation"): the motion turns about two non-parallel axes (a scale-free ratio), it turns about
// the weakest of them by more than odometry noise could fake, and the rotation about that axis
// is known well enough from the noise the residuals show. The last two count only the pairs
// that turned beyond the noise.
struct HandEyeOptions {
  int robust_iterations = 5;
  double huber_threshold_rad = 0.005;  // angular residual where Huber weights start
  // The second smallest singular value of the stacked system exceeds this fraction of the
  // largest (rotation about two non-parallel axes).
  double min_singular_value_ratio = 0.02;
  // A pair counts as motion when its IMU rotation exceeds this many residual sigmas (per
  // axis): its rotation axis is then known to better than 30 deg. Smaller rotations are noise
  // with a random axis, and a thousand of them fake rotation about any axis.
  double min_turning_pair_sigmas = 2.0;
  // The standard deviation of the rotation about the weakest axis is at most this. The
  // hand-eye only has to start the batch inside its basin, which reaches 20 deg
  // (docs/estimation.md): two sigmas. The figure assumes independent pairs; the initializer's
  // pairs overlap, which makes it optimistic (the 60 s urban pipeline log: 4 deg predicted,
  // 23 deg off about the vertical, which the inertial fit then corrects).
  double max_weakest_axis_std_rad = 10.0 * kDegToRad;
  // The turning pairs turn about the weakest axis by at least this much (root-sum-square over
  // the pairs of the rotation chord across that axis): the limit above at a per-axis pair noise
  // of 0.2 deg, the upper end of what the simulated urban drives' LiDAR odometry shows
  // (0.04-0.33 deg). It holds where a log's own residuals understate its noise.
  double min_weakest_axis_rotation_rad = 0.02;
};

struct HandEyeRotation {
  bool observable = false;
  std::string reason;
  Eigen::Quaterniond q_I_L = Eigen::Quaterniond::Identity();
  double rms_residual_rad = 0.0;
  double singular_value_ratio = 0.0;  // second smallest / largest
  // The pairs that turned by more than min_turning_pair_sigmas, their motion about the
  // weakest axis (sqrt(s2^2 - s3^2) of their weighted stacked system) and the standard
  // deviation of the rotation about it (infinite without such motion).
  int turning_pairs = 0;
  double weakest_axis_rotation_rad = 0.0;
  double weakest_axis_std_rad = 0.0;
};

// Solves R_I_ij R_I_L = R_I_L R_L_ij for pairs of simultaneous relative rotations
// (quaternion form (Q_L(q_I) - Q_R(q_L)) q_I_L = 0, smallest right singular vector, with
// Huber re-weighting).
HandEyeRotation SolveHandEyeRotation(const std::vector<Eigen::Quaterniond>& imu_rotations,
                                     const std::vector<Eigen::Quaterniond>& lidar_rotations,
                                     const HandEyeOptions& options = {});

// ---- 4. Hand-eye translation.

struct HandEyeTranslation {
  Eigen::Vector3d p_I_L = Eigen::Vector3d::Zero();
  // Per axis of the IMU frame: whether the rotations excited it (singular value of the
  // stacked (R_I_ij - I) above the threshold).
  Eigen::Matrix<bool, 3, 1> observable = Eigen::Matrix<bool, 3, 1>::Constant(false);
  Eigen::Vector3d singular_values = Eigen::Vector3d::Zero();
};

// Least squares for (R_I_ij - I) p_I_L = R_I_L t_L_ij - t_I_ij over pairs of simultaneous
// relative motions; unexcited directions keep the prior value `p_I_L_prior`.
HandEyeTranslation SolveHandEyeTranslation(const std::vector<Eigen::Quaterniond>& imu_rotations,
                                           const std::vector<Eigen::Vector3d>& imu_translations,
                                           const std::vector<Eigen::Vector3d>& lidar_translations,
                                           const Eigen::Quaterniond& q_I_L,
                                           const Eigen::Vector3d& p_I_L_prior,
                                           double min_singular_value = 0.1);

}  // namespace estimation
}  // namespace autocal
