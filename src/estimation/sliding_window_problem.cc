// The window problem of the sliding window (docs/sliding_window.md, "One update" steps 3-5):
// building it, solving it, marginalizing its oldest keyframe and its calibration covariance.
#include "autocal/estimation/sliding_window.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/factors/imu_factor.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/factors/point_to_sweep_plane_factor.h"
#include "autocal/geometry/se3.h"
#include "estimation/sliding_window_internal.h"

namespace autocal {
namespace estimation {

using internal::AttachedFactor;
using internal::StateBlocks;

namespace {

// The LiDAR pose of a sweep at its reference instant (point time 0) under the current
// estimate: T_W_L = T_W_I(t) T_I_L, T_W_I(t) from Eq. P1-P3 at delta = 0.
geometry::Pose3d SweepLidarPose(const SlidingWindowState& kf, const factors::PointMotion& m,
                                const Eigen::Vector3d& g_W, const sensors::Calibration& c) {
  const factors::PropagatedPose<double> pose =
      factors::PropagateKeyframe(kf.q_W_I, kf.p_W_I, kf.v_W_I, 0.0, m, g_W);
  const Eigen::Quaterniond q_W_I(pose.R_W_I);
  return geometry::Pose3d(q_W_I * c.q_I_L, q_W_I * c.p_I_L + pose.p_W_I);
}

// The IMU motion table of a keyframe's sweep, from the keyframe to its last point at the
// offset estimate (clamped to the IMU received so far).
ImuMotionTable SweepMotionTable(const sensors::ImuSamples& imu, const SlidingWindowState& kf,
                                const lidar::LidarSweep& sweep, double sweep_duration_s,
                                double offset_s) {
  const int64_t end_ns = std::clamp(sweep.t_ns + SecondsToNs(sweep_duration_s + offset_s),
                                    kf.t_ns, imu.back().t_ns);
  return ImuMotionTable(imu, kf.t_ns, end_ns, kf.b_g, kf.b_a);
}

// The points `indices` of a keyframe's sweep in W at the current estimate (Eq. P1-P4 at
// delta = 0).
Eigen::Matrix3Xd SweepPointsInWorld(const ImuMotionTable& table, const SlidingWindowState& kf,
                                    const lidar::LidarSweep& sweep,
                                    const std::vector<int>& indices, const Eigen::Vector3d& g_W,
                                    const sensors::Calibration& c) {
  Eigen::Matrix3Xd points_W(3, static_cast<Eigen::Index>(indices.size()));
  Eigen::Index column = 0;
  for (int i : indices) {
    const factors::PointMotion m =
        table.At(sweep.t_ns + SecondsToNs(sweep.cloud.time_s(i) + c.time_offset_lidar_imu_s));
    points_W.col(column++) = factors::PointInWorld(kf.q_W_I, kf.p_W_I, kf.v_W_I, m, g_W, c.q_I_L,
                                                   c.p_I_L, sweep.cloud.points.col(i));
  }
  return points_W;
}

}  // namespace

std::unique_ptr<SlidingWindowEstimator::ProblemBuild> SlidingWindowEstimator::BuildProblem(
    bool with_points) {
  auto build = std::make_unique<ProblemBuild>();
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  build->problem = std::make_unique<ceres::Problem>(problem_options);
  ceres::Problem& problem = *build->problem;
  geometry::RightQuaternionManifold* manifold = &quaternion_manifold_;
  sensors::Calibration& c = calibration_;

  for (const auto& kf : window_) {
    std::vector<double*> blocks = StateBlocks(&kf->state);
    problem.AddParameterBlock(blocks[0], 4, manifold);
    for (size_t i = 1; i < blocks.size(); ++i) problem.AddParameterBlock(blocks[i], 3);
  }
  const SlidingWindowEstimatedBlocks& e = options_.estimate;
  const std::vector<std::pair<double*, bool>> calibration_blocks = {
      {c.q_I_L.coeffs().data(), e.extrinsic_rotation}, {c.p_I_L.data(), e.extrinsic_translation},
      {&c.time_offset_lidar_imu_s, e.time_offset},     {&c.wheel_radius_left_m, e.wheel_radii},
      {&c.wheel_radius_right_m, e.wheel_radii},         {&c.track_width_m, e.track_width},
      {c.q_I_V.coeffs().data(), e.vehicle_frame},       {c.p_I_V.data(), e.vehicle_frame},
      {c.p_I_A.data(), e.gnss_lever_arm}};
  problem.AddParameterBlock(c.q_I_L.coeffs().data(), 4, manifold);
  problem.AddParameterBlock(c.q_I_V.coeffs().data(), 4, manifold);
  problem.AddParameterBlock(c.p_I_L.data(), 3);
  problem.AddParameterBlock(c.p_I_V.data(), 3);
  problem.AddParameterBlock(c.p_I_A.data(), 3);
  for (double* scalar : {&c.time_offset_lidar_imu_s, &c.wheel_radius_left_m,
                         &c.wheel_radius_right_m, &c.track_width_m}) {
    problem.AddParameterBlock(scalar, 1);
  }
  for (const auto& [block, estimated] : calibration_blocks) {
    if (!estimated) problem.SetParameterBlockConstant(block);
  }

  const auto add = [&problem](const AttachedFactor& f) {
    problem.AddResidualBlock(f.cost.get(), f.loss, f.blocks);
  };
  for (const AttachedFactor& f : calibration_priors_) add(f);
  for (size_t k = 0; k < window_.size(); ++k) {
    WindowKeyframe& kf = *window_[k];
    for (const AttachedFactor& f : kf.factors) add(f);
    if (k == 0) continue;
    build->owned.emplace_back(factors::ImuFactor::Create(*kf.imu_from_previous));
    std::vector<double*> blocks = StateBlocks(&window_[k - 1]->state);
    for (double* b : StateBlocks(&kf.state)) blocks.push_back(b);
    problem.AddResidualBlock(build->owned.back().get(), imu_loss_.get(), blocks);
  }
  if (prior_) problem.AddResidualBlock(prior_.get(), nullptr, prior_->parameter_pointers());
  if (with_points) AddPointFactors(build.get());
  return build;
}

// Point-to-plane factors between window sweeps (Eq. P6, docs/sliding_window.md "Association"):
// every window sweep is deskewed into W at the current estimate into its own plane map, used
// for association only. A residual point of keyframe k is paired with the plane found for it
// in the sweep of keyframe k + o, the window offsets o tried in the order of
// partner_keyframe_offsets (starting at a different one for consecutive points); the plane is
// stored in that sweep's LiDAR frame at its reference instant, so in the solve it moves with
// the partner keyframe's q, p, v and with q_I_L, p_I_L and the time offset.
void SlidingWindowEstimator::AddPointFactors(ProblemBuild* build) {
  sensors::Calibration& c = calibration_;
  const double offset_lin = c.time_offset_lidar_imu_s;

  struct LidarKeyframe {
    WindowKeyframe* kf;
    ImuMotionTable table;
    std::unique_ptr<PlaneMap> map;
    factors::PointMotion reference_motion;
    geometry::Pose3d T_W_L;  // at the reference instant
  };
  std::vector<LidarKeyframe> sweeps;
  for (const auto& kf : window_) {
    if (!kf->sweep) continue;
    sweeps.push_back({kf.get(), SweepMotionTable(imu_, kf->state, *kf->sweep,
                                                 kf->sweep_duration_s, offset_lin),
                      nullptr, factors::PointMotion(), geometry::Pose3d()});
  }
  const auto motion_of = [&](const LidarKeyframe& s, int point) {
    const lidar::LidarSweep& sweep = *s.kf->sweep;
    return s.table.At(sweep.t_ns + SecondsToNs(sweep.cloud.time_s(point) + offset_lin));
  };
  for (LidarKeyframe& s : sweeps) {
    s.map = std::make_unique<PlaneMap>(
        SweepPointsInWorld(s.table, s.kf->state, *s.kf->sweep, s.kf->map_points, g_W_, c),
        options_.plane_map);
    s.reference_motion = s.table.At(s.kf->sweep->t_ns + SecondsToNs(offset_lin));
    s.T_W_L = SweepLidarPose(s.kf->state, s.reference_motion, g_W_, c);
  }
  const std::vector<int>& partners = options_.partner_keyframe_offsets;
  const int num_sweeps = static_cast<int>(sweeps.size());
  for (int k = 0; k < num_sweeps; ++k) {
    const LidarKeyframe& s = sweeps[static_cast<size_t>(k)];
    SlidingWindowState& x = s.kf->state;
    size_t point_counter = 0;
    for (int i : s.kf->residual_points) {
      factors::PointToSweepPlaneMeasurement m;
      m.p_L = s.kf->sweep->cloud.points.col(i);
      m.motion = motion_of(s, i);
      const Eigen::Vector3d p_W = factors::PointInWorld(x.q_W_I, x.p_W_I, x.v_W_I, m.motion, g_W_,
                                                        c.q_I_L, c.p_I_L, m.p_L);
      const size_t first = point_counter++;
      int partner = -1;
      lidar::Plane plane_W;
      for (size_t attempt = 0; attempt < partners.size() && partner < 0; ++attempt) {
        const int j = k + partners[(first + attempt) % partners.size()];
        if (j < 0 || j >= num_sweeps || j == k) continue;
        if (sweeps[static_cast<size_t>(j)].map->FindPlane(p_W, &plane_W) &&
            std::abs(plane_W.SignedDistance(p_W)) <= options_.max_point_to_plane_m) {
          partner = j;
        }
      }
      if (partner < 0) continue;
      const LidarKeyframe& other = sweeps[static_cast<size_t>(partner)];
      // The plane n . p_W + d = 0 in L_j (Eq. SW3): n_L = R_W_Lj^T n, d_L = d + n . t_W_Lj.
      m.plane_L.normal = other.T_W_L.q.conjugate() * plane_W.normal;
      m.plane_L.d = plane_W.d + plane_W.normal.dot(other.T_W_L.p);
      m.plane_motion = other.reference_motion;
      m.sigma_m = options_.point_sigma_m;
      m.offset_linearization_s = offset_lin;
      SlidingWindowState& y = other.kf->state;
      build->owned.push_back(std::make_unique<factors::PointToSweepPlaneFactor>(m, g_W_));
      build->point_blocks.push_back(build->problem->AddResidualBlock(
          build->owned.back().get(), lidar_loss_.get(), x.q_W_I.coeffs().data(), x.p_W_I.data(),
          x.v_W_I.data(), y.q_W_I.coeffs().data(), y.p_W_I.data(), y.v_W_I.data(),
          c.q_I_L.coeffs().data(), c.p_I_L.data(), &c.time_offset_lidar_imu_s));
    }
  }
}

void SlidingWindowEstimator::Solve(ProblemBuild* build) {
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options_.solver_iterations;
  solver_options.num_threads = options_.num_threads;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, build->problem.get(), &summary);
  if (!summary.IsSolutionUsable()) {
    throw Error("SlidingWindowEstimator: the solver failed: " + summary.message);
  }
  for (auto& kf : window_) kf->state.q_W_I.normalize();

  last_associated_points_ = static_cast<int>(build->point_blocks.size());
  last_point_rms_m_ = 0.0;
  if (build->point_blocks.empty()) return;
  ceres::Problem::EvaluateOptions evaluate;
  evaluate.residual_blocks = build->point_blocks;
  evaluate.apply_loss_function = false;
  std::vector<double> residuals;
  build->problem->Evaluate(evaluate, nullptr, &residuals, nullptr, nullptr);
  double sum_sq = 0.0;
  for (double r : residuals) sum_sq += r * r;
  last_point_rms_m_ =
      options_.point_sigma_m * std::sqrt(sum_sq / static_cast<double>(residuals.size()));
}

// Eq. M1-M3 over every factor touching the oldest keyframe: its prior or the previous
// marginalization prior, its IMU factor to the next keyframe, its wheel/GNSS factors and the
// point factors that pair its sweep with other window sweeps (either way round). The result
// replaces the previous prior, which it includes.
std::unique_ptr<MarginalizationPrior> SlidingWindowEstimator::MarginalizeOldest(
    ProblemBuild* build) {
  const std::vector<double*> blocks = StateBlocks(&window_.front()->state);
  if (prior_) {
    const std::vector<double*> kept = prior_->parameter_pointers();
    if (std::find(kept.begin(), kept.end(), blocks[0]) == kept.end()) {
      throw Error("SlidingWindowEstimator: the marginalization prior does not reach the oldest "
                  "keyframe");
    }
  }
  return Marginalize(build->problem.get(), blocks, options_.marginalization);
}

CalibrationCovariance SlidingWindowEstimator::ComputeCalibrationCovariance(
    double min_reciprocal_condition_number) {
  const std::unique_ptr<ProblemBuild> build = BuildProblem(/*with_points=*/!imu_.empty());
  sensors::Calibration& c = calibration_;
  const SlidingWindowEstimatedBlocks& e = options_.estimate;
  struct Block {
    const char* name;
    const double* values;
    int tangent_size;
    bool estimated;
  };
  const Block all[] = {
      {"q_I_L", c.q_I_L.coeffs().data(), 3, e.extrinsic_rotation},
      {"p_I_L", c.p_I_L.data(), 3, e.extrinsic_translation},
      {"time_offset_lidar_imu_s", &c.time_offset_lidar_imu_s, 1, e.time_offset},
      {"wheel_radius_left_m", &c.wheel_radius_left_m, 1, e.wheel_radii},
      {"wheel_radius_right_m", &c.wheel_radius_right_m, 1, e.wheel_radii},
      {"track_width_m", &c.track_width_m, 1, e.track_width},
      {"q_I_V", c.q_I_V.coeffs().data(), 3, e.vehicle_frame},
      {"p_I_V", c.p_I_V.data(), 3, e.vehicle_frame},
      {"p_I_A", c.p_I_A.data(), 3, e.gnss_lever_arm}};
  CalibrationCovariance out;
  std::vector<const double*> blocks;
  int size = 0;
  for (const Block& b : all) {
    if (!b.estimated) continue;
    out.names.push_back(b.name);
    out.offsets.push_back(size);
    blocks.push_back(b.values);
    size += b.tangent_size;
  }
  out.covariance = Eigen::MatrixXd::Zero(size, size);
  if (blocks.empty()) return out;

  ceres::Covariance::Options covariance_options;
  covariance_options.algorithm_type = ceres::DENSE_SVD;
  covariance_options.null_space_rank = -1;
  covariance_options.min_reciprocal_condition_number = min_reciprocal_condition_number;
  covariance_options.num_threads = options_.num_threads;
  ceres::Covariance covariance(covariance_options);
  std::vector<std::pair<const double*, const double*>> pairs;
  for (size_t i = 0; i < blocks.size(); ++i) {
    for (size_t j = i; j < blocks.size(); ++j) pairs.emplace_back(blocks[i], blocks[j]);
  }
  if (!covariance.Compute(pairs, build->problem.get())) {
    throw Error("SlidingWindowEstimator: ceres::Covariance failed on the window problem");
  }
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> joint(size, size);
  if (!covariance.GetCovarianceMatrixInTangentSpace(blocks, joint.data())) {
    throw Error("SlidingWindowEstimator: ceres::Covariance could not return the calibration "
                "covariance");
  }
  out.covariance = joint;
  return out;
}

}  // namespace estimation
}  // namespace autocal
