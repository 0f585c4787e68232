// The window problem of the sliding window (docs/sliding_window.md, "One update" steps 3-5):
// associating the points, building it, solving it, marginalizing its oldest keyframe and its
// calibration covariance.
#include "autocal/estimation/sliding_window.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"
#include "autocal/common/time.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/factors/imu_factor.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "autocal/geometry/se3.h"
#include "autocal/geometry/so3.h"
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

// Eq. SW4: the largest displacement of a point within `range_m` of the origin between the
// poses `before` and `after` of its frame, |dp| + angle(dq) range_m with (dq, dp) = before^-1
// after.
double MaxPointMotion(const geometry::Pose3d& before, const geometry::Pose3d& after,
                      double range_m) {
  const geometry::Pose3d change = before.Inverse() * after;
  return change.p.norm() +
         geometry::AngularDistance(change.q, Eigen::Quaterniond::Identity()) * range_m;
}

}  // namespace

// Step 3 (docs/sliding_window.md, "Association" and "Reuse between updates"). Every window
// sweep j gets its IMU motion table from keyframe j at the current estimate and its LiDAR pose
// at the reference instant (point time 0), T_W_Lj = T_W_I(t_j) T_I_L. Its plane map holds the
// map points deskewed into L_j at that instant; it is rebuilt when the deskew moved a point by
// more than map_rebuild_tolerance_m (Eq. SW4). A keyframe due for pairing (below) places each
// residual point p_W in W at the current
// estimate and tries the sweeps j = k + o for the offsets o of partner_keyframe_offsets
// (starting at a different one for consecutive points): the first that holds a plane within
// max_point_to_plane_m of T_Lj_W p_W is its partner. The plane is kept in L_j (Eq. SW3), so in
// the solve it moves with keyframe j's q, p, v and with q_I_L, p_I_L and the time offset. The
// points of keyframe k on planes of sweep j form one group factor (Eq. P9).
void SlidingWindowEstimator::AssociatePoints() {
  const sensors::Calibration& c = calibration_;
  const double offset_lin = c.time_offset_lidar_imu_s;

  struct LidarKeyframe {
    WindowKeyframe* kf;
    std::optional<ImuMotionTable> table;
    factors::PointMotion reference_motion;
    geometry::Pose3d T_W_Lj;  // at the reference instant
    geometry::Pose3d T_Lj_W;
  };
  std::vector<LidarKeyframe> sweeps;
  for (const auto& kf : window_) {
    if (kf->sweep) sweeps.push_back({kf.get(), std::nullopt, factors::PointMotion(), {}, {}});
  }
  const int num_sweeps = static_cast<int>(sweeps.size());
  const auto motion_at = [offset_lin](const LidarKeyframe& s, double point_time_s) {
    return s.table->At(s.kf->sweep->t_ns + SecondsToNs(point_time_s + offset_lin));
  };

  ParallelFor(0, num_sweeps, options_.num_threads, [&](int64_t begin, int64_t end, int) {
    for (int64_t k = begin; k < end; ++k) {
      LidarKeyframe& s = sweeps[static_cast<size_t>(k)];
      WindowKeyframe& kf = *s.kf;
      s.table.emplace(
          SweepMotionTable(imu_, kf.state, *kf.sweep, kf.sweep_duration_s, offset_lin));
      s.reference_motion = motion_at(s, 0.0);
      s.T_W_Lj = SweepLidarPose(kf.state, s.reference_motion, g_W_, c);
      s.T_Lj_W = s.T_W_Lj.Inverse();
      // Eq. SW4: the deskew's pose at the sweep's last point, T_L0_L(tau_max); a point at
      // range r moves by at most |dp| + angle(dq) r when it changes by (dq, dp).
      const geometry::Pose3d deskew_end =
          s.T_Lj_W * SweepLidarPose(kf.state, motion_at(s, kf.sweep_duration_s), g_W_, c);
      if (kf.plane_map && MaxPointMotion(kf.map_deskew_end, deskew_end, kf.map_max_range_m) <=
                              options_.map_rebuild_tolerance_m) {
        continue;
      }
      const Eigen::Matrix3Xd points_W =
          SweepPointsInWorld(*s.table, kf.state, *kf.sweep, kf.map_points, g_W_, c);
      const Eigen::Matrix3Xd points_L =
          (s.T_Lj_W.q.toRotationMatrix() * points_W).colwise() + s.T_Lj_W.p;
      kf.plane_map = std::make_unique<PlaneMap>(points_L, options_.plane_map);
      kf.map_deskew_end = deskew_end;
      kf.map_max_range_m = 0.0;
      for (int i : kf.map_points) {
        kf.map_max_range_m = std::max(kf.map_max_range_m, kf.sweep->cloud.points.col(i).norm());
      }
    }
  });

  // A keyframe is due for pairing when it is new, when a sweep at one of its partner offsets
  // entered the window or one of its partners left it since its last pairing (so that its
  // pairs are those a fresh association would try), or when one of its partners moved
  // relative to it by more than reassociation_tolerance_m at the range of its farthest
  // residual point (Eq. SW4).
  std::map<int, int> sweep_of_id;
  for (int k = 0; k < num_sweeps; ++k) sweep_of_id[sweeps[static_cast<size_t>(k)].kf->id] = k;
  const auto relative_pose = [&sweeps](int j, int k) {
    return sweeps[static_cast<size_t>(j)].T_Lj_W * sweeps[static_cast<size_t>(k)].T_W_Lj;
  };
  std::vector<int> due;
  for (int k = 0; k < num_sweeps; ++k) {
    const WindowKeyframe& kf = *sweeps[static_cast<size_t>(k)].kf;
    bool is_due = !kf.paired || kf.lost_partner;
    for (int o : options_.partner_keyframe_offsets) {
      const int partner_id = kf.id + o;
      if (partner_id > kf.newest_id_at_pairing && partner_id <= window_.back()->id) {
        is_due = true;
      }
    }
    for (size_t g = 0; g < kf.point_groups.size() && !is_due; ++g) {
      const internal::SweepPointGroup& group = kf.point_groups[g];
      is_due = MaxPointMotion(group.T_Lj_Lk, relative_pose(sweep_of_id.at(group.partner_id), k),
                              kf.residual_max_range_m) > options_.reassociation_tolerance_m;
    }
    if (is_due) due.push_back(k);
  }
  const std::vector<int>& partners = options_.partner_keyframe_offsets;
  ParallelFor(0, static_cast<int64_t>(due.size()), options_.num_threads,
              [&](int64_t begin, int64_t end, int) {
    for (int64_t d = begin; d < end; ++d) {
      const int k = due[static_cast<size_t>(d)];
      const LidarKeyframe& s = sweeps[static_cast<size_t>(k)];
      WindowKeyframe& kf = *s.kf;
      SlidingWindowState& x = kf.state;
      std::map<int, std::vector<factors::PointToSweepPlaneMeasurement>> by_partner;
      size_t point_counter = 0;
      for (int i : kf.residual_points) {
        factors::PointToSweepPlaneMeasurement m;
        m.p_L = kf.sweep->cloud.points.col(i);
        m.motion = motion_at(s, kf.sweep->cloud.time_s(i));
        const Eigen::Vector3d p_W = factors::PointInWorld(x.q_W_I, x.p_W_I, x.v_W_I, m.motion,
                                                          g_W_, c.q_I_L, c.p_I_L, m.p_L);
        const size_t first = point_counter++;
        int partner = -1;
        for (size_t attempt = 0; attempt < partners.size() && partner < 0; ++attempt) {
          const int j = k + partners[(first + attempt) % partners.size()];
          if (j < 0 || j >= num_sweeps || j == k) continue;
          const LidarKeyframe& other = sweeps[static_cast<size_t>(j)];
          const Eigen::Vector3d p_Lj = other.T_Lj_W * p_W;
          if (other.kf->plane_map->FindPlane(p_Lj, &m.plane_L) &&
              std::abs(m.plane_L.SignedDistance(p_Lj)) <= options_.max_point_to_plane_m) {
            partner = j;
          }
        }
        if (partner < 0) continue;
        m.plane_motion = sweeps[static_cast<size_t>(partner)].reference_motion;
        m.sigma_m = options_.point_sigma_m;
        m.offset_linearization_s = offset_lin;
        by_partner[partner].push_back(m);
      }
      kf.point_groups.clear();
      kf.residual_max_range_m = 0.0;
      for (int i : kf.residual_points) {
        kf.residual_max_range_m =
            std::max(kf.residual_max_range_m, kf.sweep->cloud.points.col(i).norm());
      }
      for (const auto& [j, measurements] : by_partner) {
        WindowKeyframe& other = *sweeps[static_cast<size_t>(j)].kf;
        SlidingWindowState& y = other.state;
        internal::SweepPointGroup group;
        group.partner_id = other.id;
        group.T_Lj_Lk = relative_pose(j, k);
        group.factor = std::make_unique<factors::PointToSweepPlaneGroupFactor>(
            measurements, g_W_, options_.loss.lidar);
        if (group.factor->num_residuals() > internal::CompressedPointGroup::kRows) {
          group.compressed = std::make_unique<internal::CompressedPointGroup>(group.factor.get());
        }
        group.parameters = {x.q_W_I.coeffs().data(), x.p_W_I.data(), x.v_W_I.data(),
                            y.q_W_I.coeffs().data(), y.p_W_I.data(), y.v_W_I.data(),
                            calibration_.q_I_L.coeffs().data(), calibration_.p_I_L.data(),
                            &calibration_.time_offset_lidar_imu_s};
        kf.point_groups.push_back(std::move(group));
      }
      kf.paired = true;
      kf.newest_id_at_pairing = window_.back()->id;
      kf.lost_partner = false;
    }
  });
}

std::unique_ptr<SlidingWindowEstimator::ProblemBuild> SlidingWindowEstimator::BuildProblem() {
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
  // The point groups carry the LiDAR loss themselves (Eq. P9).
  for (const auto& kf : window_) {
    for (const internal::SweepPointGroup& g : kf->point_groups) {
      problem.AddResidualBlock(g.solver_cost(), nullptr, g.parameters);
    }
  }
  return build;
}

std::vector<double> SlidingWindowEstimator::PointDistances() const {
  std::vector<double> distances;
  for (const auto& kf : window_) {
    for (const internal::SweepPointGroup& g : kf->point_groups) {
      const size_t first = distances.size();
      distances.resize(first + static_cast<size_t>(g.factor->num_points()));
      g.factor->WhitenedDistances(g.parameters.data(), distances.data() + first);
    }
  }
  for (double& r : distances) r *= options_.point_sigma_m;
  return distances;
}

void SlidingWindowEstimator::Solve(ProblemBuild* build) {
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = options_.solver_iterations;
  solver_options.function_tolerance = options_.solver_function_tolerance;
  solver_options.num_threads = options_.num_threads;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, build->problem.get(), &summary);
  if (!summary.IsSolutionUsable()) {
    throw Error("SlidingWindowEstimator: the solver failed: " + summary.message);
  }
  timing_.solver_iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
  for (auto& kf : window_) kf->state.q_W_I.normalize();

  const std::vector<double> distances = PointDistances();
  last_associated_points_ = static_cast<int>(distances.size());
  last_point_rms_m_ = 0.0;
  if (distances.empty()) return;
  double sum_sq = 0.0;
  for (double r : distances) sum_sq += r * r;
  last_point_rms_m_ = std::sqrt(sum_sq / static_cast<double>(distances.size()));
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
  const std::unique_ptr<ProblemBuild> build = BuildProblem();
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
