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
#include "estimation/sliding_window_internal.h"

namespace autocal {
namespace estimation {

using internal::AttachedFactor;
using internal::StateBlocks;

namespace {

// The world position of a point under the current estimate (Eq. P1-P4 at delta = 0).
Eigen::Vector3d PointInWorld(const SlidingWindowState& kf, const factors::PointMotion& m,
                             const Eigen::Vector3d& g_W, const sensors::Calibration& c,
                             const Eigen::Vector3d& p_L) {
  const Eigen::Quaterniond q_t = kf.q_W_I * m.delta_q;
  const Eigen::Vector3d p_t = kf.p_W_I + kf.v_W_I * m.dt_s + 0.5 * g_W * m.dt_s * m.dt_s +
                              kf.q_W_I * m.delta_p;
  return q_t * (c.q_I_L * p_L + c.p_I_L) + p_t;
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

// Point-to-plane factors (Eq. P1-P4): every window sweep is deskewed into W at the current
// estimate into one map tagged by keyframe, held fixed during the solve; each keyframe's
// residual points are associated with planes of keyframes at least min_tag_gap away.
void SlidingWindowEstimator::AddPointFactors(ProblemBuild* build) {
  sensors::Calibration& c = calibration_;
  const double offset_lin = c.time_offset_lidar_imu_s;
  const int64_t newest_imu_ns = imu_.back().t_ns;

  std::vector<WindowKeyframe*> lidar_keyframes;
  std::vector<ImuMotionTable> tables;
  Eigen::Index map_size = 0;
  for (const auto& kf : window_) {
    if (!kf->sweep) continue;
    const int64_t end_ns = std::clamp(
        kf->sweep->t_ns + SecondsToNs(kf->sweep_duration_s + offset_lin), kf->state.t_ns,
        newest_imu_ns);
    tables.emplace_back(imu_, kf->state.t_ns, end_ns, kf->state.b_g, kf->state.b_a);
    lidar_keyframes.push_back(kf.get());
    map_size += static_cast<Eigen::Index>(kf->map_points.size());
  }
  if (map_size == 0) return;
  const auto motion_of = [&](size_t k, int point) {
    const lidar::LidarSweep& sweep = *lidar_keyframes[k]->sweep;
    return tables[k].At(sweep.t_ns + SecondsToNs(sweep.cloud.time_s(point) + offset_lin));
  };

  Eigen::Matrix3Xd map_points(3, map_size);
  std::vector<int> tags;
  tags.reserve(static_cast<size_t>(map_size));
  Eigen::Index column = 0;
  for (size_t k = 0; k < lidar_keyframes.size(); ++k) {
    const WindowKeyframe& kf = *lidar_keyframes[k];
    for (int i : kf.map_points) {
      map_points.col(column++) =
          PointInWorld(kf.state, motion_of(k, i), g_W_, c, kf.sweep->cloud.points.col(i));
      tags.push_back(kf.id);
    }
  }
  const PlaneMap map(std::move(map_points), std::move(tags), options_.plane_map);

  for (size_t k = 0; k < lidar_keyframes.size(); ++k) {
    WindowKeyframe& kf = *lidar_keyframes[k];
    for (int i : kf.residual_points) {
      factors::PointToPlaneMeasurement m;
      m.p_L = kf.sweep->cloud.points.col(i);
      m.motion = motion_of(k, i);
      if (!map.FindPlane(PointInWorld(kf.state, m.motion, g_W_, c, m.p_L), kf.id, &m.plane)) {
        continue;
      }
      m.sigma_m = options_.point_sigma_m;
      m.offset_linearization_s = offset_lin;
      build->owned.push_back(std::make_unique<factors::PointToPlaneFactor>(m, g_W_));
      build->point_blocks.push_back(build->problem->AddResidualBlock(
          build->owned.back().get(), lidar_loss_.get(), kf.state.q_W_I.coeffs().data(),
          kf.state.p_W_I.data(), kf.state.v_W_I.data(), c.q_I_L.coeffs().data(), c.p_I_L.data(),
          &c.time_offset_lidar_imu_s));
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
// point factors of its sweep. The result replaces the previous prior, which it includes.
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
