#include "autocal/estimation/lidar_inertial_batch.h"

#include "autocal/estimation/keyframe_sensor_factors.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"
#include "autocal/common/time.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/factors/prior_factors.h"
#include "autocal/factors/point_to_sweep_plane_factor.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "autocal/geometry/se3.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "estimation/firing_poses.h"
#include "estimation/point_selection.h"

namespace autocal {
namespace estimation {

namespace {

// 1-sigma of the gauge prior on the first keyframe's yaw: a direction no factor informs, so
// any weight fixes it without pulling on the data.
constexpr double kGaugeYawSigmaRad = 1e-6;

// The LiDAR pose of sweep j at its reference instant (point time 0) under the current
// estimate: T_W_L = T_W_I(t) T_I_L with T_W_I(t) from Eq. (P1-P3) at delta = 0.
geometry::Pose3d SweepLidarPose(const Keyframe& kf, const factors::PointMotion& m,
                                const Eigen::Vector3d& g_W, const Eigen::Quaterniond& q_I_L,
                                const Eigen::Vector3d& p_I_L) {
  const factors::PropagatedPose<double> pose =
      factors::PropagateKeyframe(kf.q_W_I, kf.p_W_I, kf.v_W_I, 0.0, m, g_W);
  const Eigen::Quaterniond q_W_I(pose.R_W_I);
  return geometry::Pose3d(q_W_I * q_I_L, q_W_I * p_I_L + pose.p_W_I);
}

struct SweepSelection {
  std::vector<int> residual_points;
  std::vector<int> map_points;
};

// Fills report->covariance for the calibration blocks that the problem estimates; held
// blocks and axes keep zero rows.
void ComputeCovariance(ceres::Problem* problem, sensors::Calibration* calibration,
                       const std::vector<int>& held_p_axes, LidarInertialBatchReport* report) {
  double* q = calibration->q_I_L.coeffs().data();
  double* p = calibration->p_I_L.data();
  double* o = &calibration->time_offset_lidar_imu_s;
  std::vector<double*> blocks;
  for (double* block : {q, p, o}) {
    if (!problem->IsParameterBlockConstant(block)) blocks.push_back(block);
  }
  if (blocks.empty()) return;
  std::vector<std::pair<const double*, const double*>> pairs;
  for (double* a : blocks) {
    for (double* b : blocks) pairs.emplace_back(a, b);
  }
  ceres::Covariance::Options covariance_options;
  covariance_options.algorithm_type = ceres::SPARSE_QR;
  ceres::Covariance covariance(covariance_options);
  if (!covariance.Compute(pairs, problem)) return;
  // Rows of the 7x7 result that each block's tangent coordinates fill (p_I_L's held axes
  // have none).
  auto rows_of = [&](const double* block) {
    if (block == q) return std::vector<int>{0, 1, 2};
    if (block == o) return std::vector<int>{6};
    std::vector<int> rows;
    for (int axis = 0; axis < 3; ++axis) {
      if (std::find(held_p_axes.begin(), held_p_axes.end(), axis) == held_p_axes.end()) {
        rows.push_back(3 + axis);
      }
    }
    return rows;
  };
  for (double* a : blocks) {
    for (double* b : blocks) {
      const std::vector<int> rows_a = rows_of(a), rows_b = rows_of(b);
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> c(rows_a.size(),
                                                                                rows_b.size());
      if (!covariance.GetCovarianceBlockInTangentSpace(a, b, c.data())) return;
      for (size_t i = 0; i < rows_a.size(); ++i) {
        for (size_t j = 0; j < rows_b.size(); ++j) {
          report->covariance(rows_a[i], rows_b[j]) = c(static_cast<Eigen::Index>(i),
                                                       static_cast<Eigen::Index>(j));
        }
      }
    }
  }
  report->covariance_ok = true;
}

}  // namespace

int64_t KeyframeTime(int64_t t_sweep_ns, double offset_s, const LidarInertialBatchOptions& options) {
  return t_sweep_ns + SecondsToNs(offset_s - options.keyframe_lead_s);
}

LidarInertialBatchReport SolveLidarInertialBatch(const sensors::ImuSamples& imu,
                                                 const std::vector<lidar::LidarSweep>& sweeps,
                                                 std::vector<Keyframe>* keyframes,
                                                 sensors::Calibration* calibration,
                                                 const LidarInertialBatchOptions& options) {
  if (keyframes->size() != sweeps.size() || sweeps.size() < 2) {
    throw Error("SolveLidarInertialBatch: need one keyframe per sweep and at least two sweeps");
  }
  const Eigen::Vector3d g_W(0.0, 0.0, -options.gravity_m_s2);
  std::vector<SweepSelection> selection(sweeps.size());
  std::vector<double> max_point_time_s(sweeps.size());
  for (size_t k = 0; k < sweeps.size(); ++k) {
    if (!sweeps[k].cloud.has_time()) throw Error("SolveLidarInertialBatch: sweeps need per-point time");
    max_point_time_s[k] = sweeps[k].cloud.size() > 0 ? sweeps[k].cloud.time_s.maxCoeff() : 0.0;
    selection[k].residual_points = internal::Thin(
        internal::OnePointPerVoxel(sweeps[k].cloud, options.residual_voxel_m, options.min_range_m),
        options.max_residuals_per_sweep);
    selection[k].map_points =
        internal::OnePointPerVoxel(sweeps[k].cloud, options.map_voxel_m, options.min_range_m);
  }

  // Parameter blocks shared by every iteration.
  double* offset = &calibration->time_offset_lidar_imu_s;
  geometry::RightQuaternionManifold quaternion_manifold;
  LidarInertialBatchReport report;
  const auto start = std::chrono::steady_clock::now();

  for (int iteration = 0; iteration < options.outer_iterations; ++iteration) {
    const sensors::Calibration before = *calibration;
    const double offset_lin = *offset;

    const auto iteration_start = std::chrono::steady_clock::now();
    // Steps 1-3 work on each sweep independently, on options.num_threads threads.
    const int num_sweeps = static_cast<int>(sweeps.size());
    const auto for_each_sweep = [&](const std::function<void(size_t)>& body) {
      ParallelFor(0, num_sweeps, options.num_threads, [&](int64_t begin, int64_t end, int) {
        for (int64_t k = begin; k < end; ++k) body(static_cast<size_t>(k));
      });
    };
    // 1. Propagate every sweep with the current estimate.
    std::vector<std::optional<ImuMotionTable>> tables(sweeps.size());
    for_each_sweep([&](size_t k) {
      const Keyframe& kf = (*keyframes)[k];
      const int64_t end_ns = sweeps[k].t_ns + SecondsToNs(max_point_time_s[k] + offset_lin);
      if (end_ns < kf.t_ns) {
        throw Error("SolveLidarInertialBatch: the time offset moved beyond the keyframe lead");
      }
      tables[k].emplace(imu, kf.t_ns, end_ns, kf.b_g, kf.b_a);
    });
    auto motion_of = [&](size_t k, int point) {
      const double tau = sweeps[k].cloud.time_s(point);
      return tables[k]->At(sweeps[k].t_ns + SecondsToNs(tau + offset_lin));
    };

    // 2. One plane map per sweep, deskewed into W with the current estimate, and each
    //    sweep's LiDAR pose at its reference instant. Early iterations accept thicker planes
    //    and weigh points less (coarse to fine), so that a calibration still far off finds
    //    associations at all.
    const double coarse = std::pow(2.0, std::max(0, options.coarse_to_fine_steps - iteration));
    lidar::PlaneMapOptions map_options = options.plane_map;
    map_options.max_plane_thickness_m *= coarse;
    const double point_sigma_m = options.point_sigma_m * coarse;
    const double max_point_to_plane_m = options.max_point_to_plane_m * coarse;
    std::vector<Eigen::Matrix3Xd> map_points_W(sweeps.size());
    std::vector<factors::PointMotion> reference_motion(sweeps.size());
    std::vector<geometry::Pose3d> T_W_L(sweeps.size());
    for_each_sweep([&](size_t j) {
      Eigen::Matrix3Xd& points = map_points_W[j];
      points.resize(3, static_cast<Eigen::Index>(selection[j].map_points.size()));
      Eigen::Index column = 0;
      const Keyframe& kf = (*keyframes)[j];
      internal::FiringPoses poses(kf.q_W_I, kf.p_W_I, kf.v_W_I, g_W);
      for (int i : selection[j].map_points) {
        const factors::PropagatedPose<double>& pose =
            poses.At(sweeps[j].cloud.time_s(i), [&] { return motion_of(j, i); });
        points.col(column++) = factors::PointInWorld(pose, calibration->q_I_L, calibration->p_I_L,
                                                     sweeps[j].cloud.points.col(i));
      }
      reference_motion[j] = tables[j]->At(sweeps[j].t_ns + SecondsToNs(offset_lin));
      T_W_L[j] = SweepLidarPose((*keyframes)[j], reference_motion[j], g_W, calibration->q_I_L,
                                calibration->p_I_L);
    });
    // The planes of sweep j come from it and its map_neighbor_sweeps neighbours on each
    // side: a denser local map, whose parts are too close in time to disagree much.
    std::vector<std::unique_ptr<lidar::PlaneMap>> maps(sweeps.size());
    for_each_sweep([&](size_t sweep) {
      const int j = static_cast<int>(sweep);
      const int first = std::max(0, j - options.map_neighbor_sweeps);
      const int last = std::min(num_sweeps - 1, j + options.map_neighbor_sweeps);
      Eigen::Index size = 0;
      for (int i = first; i <= last; ++i) size += map_points_W[static_cast<size_t>(i)].cols();
      Eigen::Matrix3Xd local(3, size);
      Eigen::Index column = 0;
      for (int i = first; i <= last; ++i) {
        const Eigen::Matrix3Xd& part = map_points_W[static_cast<size_t>(i)];
        local.middleCols(column, part.cols()) = part;
        column += part.cols();
      }
      maps[sweep] = std::make_unique<lidar::PlaneMap>(local, map_options);
    });

    // 3. Association: each point is paired with a plane of another sweep (Eq. P6). The
    //    partners are tried in the order of options.partner_sweep_offsets, starting at a
    //    different one for consecutive points, so that every sweep is tied to sweeps before
    //    and after it.
    struct Association {
      factors::PointToSweepPlaneMeasurement measurement;
      int partner;
    };
    std::vector<std::vector<Association>> associations(sweeps.size());
    const std::vector<int>& partners = options.partner_sweep_offsets;
    for_each_sweep([&](size_t sweep) {
      const int k = static_cast<int>(sweep);
      const Keyframe& kf = (*keyframes)[sweep];
      int point_counter = 0;
      internal::FiringPoses poses(kf.q_W_I, kf.p_W_I, kf.v_W_I, g_W);
      for (int i : selection[sweep].residual_points) {
        const factors::PropagatedPose<double>& pose =
            poses.At(sweeps[sweep].cloud.time_s(i), [&] { return motion_of(sweep, i); });
        factors::PointToSweepPlaneMeasurement m;
        m.p_L = sweeps[sweep].cloud.points.col(i);
        m.motion = poses.motion();
        const Eigen::Vector3d p_W =
            factors::PointInWorld(pose, calibration->q_I_L, calibration->p_I_L, m.p_L);
        const int first = point_counter++;
        int partner = -1;
        lidar::Plane plane_W;
        for (size_t attempt = 0; attempt < partners.size() && partner < 0; ++attempt) {
          const int j = k + partners[(static_cast<size_t>(first) + attempt) % partners.size()];
          if (j < 0 || j >= num_sweeps || j == k) continue;
          if (maps[static_cast<size_t>(j)]->FindPlane(p_W, &plane_W) &&
              std::abs(plane_W.SignedDistance(p_W)) <= max_point_to_plane_m) {
            partner = j;
          }
        }
        if (partner < 0) continue;
        const geometry::Pose3d& T = T_W_L[static_cast<size_t>(partner)];
        m.plane_L.normal = T.q.conjugate() * plane_W.normal;
        m.plane_L.d = plane_W.d + plane_W.normal.dot(T.p);
        m.plane_motion = reference_motion[static_cast<size_t>(partner)];
        m.sigma_m = point_sigma_m;
        m.offset_linearization_s = offset_lin;
        associations[sweep].push_back({m, partner});
      }
    });
    // 4. The problem: IMU factors between keyframes, point-to-plane factors per sweep.
    ceres::Problem::Options problem_options;
    problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    for (Keyframe& kf : *keyframes) {
      problem.AddParameterBlock(kf.q_W_I.coeffs().data(), 4, &quaternion_manifold);
    }
    problem.AddParameterBlock(calibration->q_I_L.coeffs().data(), 4, &quaternion_manifold);
    KeyframeImuOptions imu_options;
    imu_options.noise = options.imu_noise;
    imu_options.gravity_m_s2 = options.gravity_m_s2;
    imu_options.num_threads = options.num_threads;
    AddImuFactors(&problem, imu, keyframes, imu_options);
    // One residual block per pair of sweeps (Eq. P9): the points of sweep k on planes of
    // sweep j share every parameter block; the robust loss acts per point inside the factor.
    struct PointGroup {
      const factors::PointToSweepPlaneGroupFactor* factor;  // owned by the problem
      std::vector<double*> parameters;
    };
    std::vector<PointGroup> point_groups;
    int associated_points = 0;
    for (int k = 0; k < num_sweeps; ++k) {
      Keyframe& kf = (*keyframes)[static_cast<size_t>(k)];
      std::map<int, std::vector<factors::PointToSweepPlaneMeasurement>> by_partner;
      for (const Association& a : associations[static_cast<size_t>(k)]) {
        by_partner[a.partner].push_back(a.measurement);
      }
      for (const auto& [partner, measurements] : by_partner) {
        Keyframe& kf_j = (*keyframes)[static_cast<size_t>(partner)];
        PointGroup group;
        group.parameters = {kf.q_W_I.coeffs().data(),   kf.p_W_I.data(),   kf.v_W_I.data(),
                            kf_j.q_W_I.coeffs().data(), kf_j.p_W_I.data(), kf_j.v_W_I.data(),
                            calibration->q_I_L.coeffs().data(), calibration->p_I_L.data(),
                            offset};
        auto factor = std::make_unique<factors::PointToSweepPlaneGroupFactor>(
            measurements, g_W, options.point_loss);
        group.factor = factor.get();
        problem.AddResidualBlock(factor.release(), nullptr, group.parameters);
        point_groups.push_back(std::move(group));
        associated_points += static_cast<int>(measurements.size());
      }
    }
    if (point_groups.empty()) throw Error("SolveLidarInertialBatch: no point found a plane");

    // Other sensors' factors and priors, from the caller.
    if (options.add_factors) options.add_factors(&problem, keyframes, calibration);

    // Gauge: position and yaw are unobservable from IMU and LiDAR alone; roll and pitch are
    // not (gravity) and stay free, or the initializer's tilt error would be frozen in and
    // leak gravity into every acceleration. The yaw is held by a prior on the first
    // keyframe's rotation about z_W only: for the right perturbation phi, the rotation in W is
    // R0 phi, so the prior's one nonzero row is z_W^T R0 / sigma.
    if (options.hold_first_pose) {
      Keyframe& first = (*keyframes)[0];
      problem.SetParameterBlockConstant(first.p_W_I.data());
      Eigen::Matrix3d yaw_only = Eigen::Matrix3d::Zero();
      yaw_only.row(2) = first.q_W_I.normalized().toRotationMatrix().row(2) / kGaugeYawSigmaRad;
      problem.AddResidualBlock(new factors::QuaternionPriorFactor(first.q_W_I, yaw_only), nullptr,
                               first.q_W_I.coeffs().data());
    }
    if (!options.estimate_extrinsic_rotation) {
      problem.SetParameterBlockConstant(calibration->q_I_L.coeffs().data());
    }
    std::vector<int> held_axes;
    for (int axis = 0; axis < 3; ++axis) {
      if (options.hold_p_I_L_axes(axis)) held_axes.push_back(axis);
    }
    if (!options.estimate_extrinsic_translation || held_axes.size() == 3) {
      problem.SetParameterBlockConstant(calibration->p_I_L.data());
    } else if (!held_axes.empty()) {
      problem.SetManifold(calibration->p_I_L.data(), new ceres::SubsetManifold(3, held_axes));
    }
    if (!options.estimate_time_offset) problem.SetParameterBlockConstant(offset);

    // Signed point-to-plane distances (m) without the robust loss.
    auto point_distances_m = [&]() {
      std::vector<double> residuals(static_cast<size_t>(associated_points));
      double* out = residuals.data();
      for (const PointGroup& group : point_groups) {
        group.factor->WhitenedDistances(group.parameters.data(), out);
        out += group.factor->num_points();
      }
      for (double& r : residuals) r *= point_sigma_m;
      return residuals;
    };
    if (iteration == 0) report.initial_point_residuals_m = point_distances_m();

    const auto solve_start = std::chrono::steady_clock::now();
    report.seconds_association +=
        std::chrono::duration<double>(solve_start - iteration_start).count();
    // 5. Solve.
    ceres::Solver::Options solver_options;
    solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    solver_options.max_num_iterations = options.solver_iterations;
    solver_options.num_threads = options.num_threads;
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
    report.seconds_solver +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - solve_start).count();
    if (!summary.IsSolutionUsable()) {
      throw Error("SolveLidarInertialBatch: the solver failed: " + summary.message);
    }

    // 6. Point residual statistics without the robust loss.
    const std::vector<double> residuals = point_distances_m();
    double sum_sq = 0.0;
    for (double r : residuals) sum_sq += r * r;
    report.final_point_residuals_m = residuals;
    report.point_rms_m = std::sqrt(sum_sq / static_cast<double>(residuals.size()));
    report.associated_points = associated_points;
    report.final_cost = summary.final_cost;
    report.outer_iterations = iteration + 1;
    report.calibration_per_iteration.push_back(*calibration);

    if (options.progress) {
      LidarInertialBatchProgress progress;
      progress.iteration = iteration + 1;
      progress.max_iterations = options.outer_iterations;
      progress.cost = summary.final_cost;
      progress.elapsed_s =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      progress.associated_points = report.associated_points;
      options.progress(progress);
    }
    report.termination = summary.message;

    const bool converged =
        geometry::AngularDistance(before.q_I_L, calibration->q_I_L) * 180.0 / M_PI <
            options.converged_rotation_deg &&
        (before.p_I_L - calibration->p_I_L).norm() < options.converged_translation_m &&
        std::abs(before.time_offset_lidar_imu_s - calibration->time_offset_lidar_imu_s) <
            options.converged_time_offset_s;
    const bool last = (converged && iteration >= options.coarse_to_fine_steps) ||
                      iteration + 1 == options.outer_iterations;
    if (last && options.compute_covariance) ComputeCovariance(&problem, calibration, held_axes, &report);
    if (last && options.inspect_final_problem) options.inspect_final_problem(&problem);
    if (last) break;
  }
  return report;
}

}  // namespace estimation
}  // namespace autocal
