#include "autocal/estimation/lidar_inertial_batch.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <unordered_set>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/factors/imu_factor.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "autocal/sensors/imu_preintegration.h"

namespace autocal {
namespace estimation {

namespace {

// Indices of one point per occupied voxel (the first met), points closer than min_range_m
// dropped; a representative keeps its exact coordinates and time.
std::vector<int> OnePointPerVoxel(const lidar::PointCloud& cloud, double voxel_m,
                                  double min_range_m) {
  std::unordered_set<uint64_t> occupied;
  std::vector<int> out;
  const double inv = 1.0 / voxel_m;
  for (int64_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = cloud.points.col(i);
    if (p.squaredNorm() < min_range_m * min_range_m) continue;
    const auto cell = [inv](double x) {
      return static_cast<uint64_t>(static_cast<int64_t>(std::floor(x * inv)) + (1 << 20)) &
             0x1FFFFF;
    };
    const uint64_t key = (cell(p.x()) << 42) | (cell(p.y()) << 21) | cell(p.z());
    if (occupied.insert(key).second) out.push_back(static_cast<int>(i));
  }
  return out;
}

// Every k-th index so that at most max_count remain.
std::vector<int> Thin(const std::vector<int>& indices, int max_count) {
  if (static_cast<int>(indices.size()) <= max_count) return indices;
  std::vector<int> out;
  const double stride = static_cast<double>(indices.size()) / max_count;
  for (int i = 0; i < max_count; ++i) out.push_back(indices[static_cast<size_t>(i * stride)]);
  return out;
}

double MaxPointTime(const lidar::LidarSweep& sweep) {
  return sweep.cloud.has_time() ? sweep.cloud.time_s.maxCoeff() : 0.0;
}

// The world position of a point of sweep k under the current estimate (Eq. P1-P4 at
// delta = 0).
Eigen::Vector3d PointInWorld(const Keyframe& kf, const factors::PointMotion& m,
                             const Eigen::Vector3d& g_W, const Eigen::Quaterniond& q_I_L,
                             const Eigen::Vector3d& p_I_L, const Eigen::Vector3d& p_L) {
  const Eigen::Quaterniond q_t = kf.q_W_I * m.delta_q;
  const Eigen::Vector3d p_t = kf.p_W_I + kf.v_W_I * m.dt_s + 0.5 * g_W * m.dt_s * m.dt_s +
                              kf.q_W_I * m.delta_p;
  return q_t * (q_I_L * p_L + p_I_L) + p_t;
}

struct SweepSelection {
  std::vector<int> residual_points;
  std::vector<int> map_points;
};

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
  for (size_t k = 0; k < sweeps.size(); ++k) {
    if (!sweeps[k].cloud.has_time()) throw Error("SolveLidarInertialBatch: sweeps need per-point time");
    selection[k].residual_points = Thin(
        OnePointPerVoxel(sweeps[k].cloud, options.residual_voxel_m, options.min_range_m),
        options.max_residuals_per_sweep);
    selection[k].map_points =
        OnePointPerVoxel(sweeps[k].cloud, options.map_voxel_m, options.min_range_m);
  }

  // Parameter blocks shared by every iteration.
  double* offset = &calibration->time_offset_lidar_imu_s;
  geometry::RightQuaternionManifold quaternion_manifold;
  LidarInertialBatchReport report;

  for (int iteration = 0; iteration < options.outer_iterations; ++iteration) {
    const sensors::Calibration before = *calibration;
    const double offset_lin = *offset;

    // 1. Propagate every sweep with the current estimate.
    std::vector<ImuMotionTable> tables;
    tables.reserve(sweeps.size());
    for (size_t k = 0; k < sweeps.size(); ++k) {
      const Keyframe& kf = (*keyframes)[k];
      const int64_t end_ns = sweeps[k].t_ns + SecondsToNs(MaxPointTime(sweeps[k]) + offset_lin);
      if (end_ns < kf.t_ns) {
        throw Error("SolveLidarInertialBatch: the time offset moved beyond the keyframe lead");
      }
      tables.emplace_back(imu, kf.t_ns, end_ns, kf.b_g, kf.b_a);
    }
    auto motion_of = [&](size_t k, int point) {
      const double tau = sweeps[k].cloud.time_s(point);
      return tables[k].At(sweeps[k].t_ns + SecondsToNs(tau + offset_lin));
    };

    // 2. The plane map from all sweeps, deskewed into W, each point tagged with its sweep so
    //    that a sweep is associated only with what other sweeps saw. Early iterations accept
    //    thicker planes and weigh points less (coarse to fine), so that a calibration still
    //    far off finds associations at all.
    const double coarse = std::pow(2.0, std::max(0, options.coarse_to_fine_steps - iteration));
    PlaneMapOptions map_options = options.plane_map;
    map_options.max_plane_thickness_m *= coarse;
    const double point_sigma_m = options.point_sigma_m * coarse;
    size_t map_size = 0;
    for (const auto& s : selection) map_size += s.map_points.size();
    Eigen::Matrix3Xd map_points(3, static_cast<Eigen::Index>(map_size));
    std::vector<int> map_tags;
    map_tags.reserve(map_size);
    Eigen::Index column = 0;
    for (size_t k = 0; k < sweeps.size(); ++k) {
      for (int i : selection[k].map_points) {
        map_points.col(column++) =
            PointInWorld((*keyframes)[k], motion_of(k, i), g_W, calibration->q_I_L,
                         calibration->p_I_L, sweeps[k].cloud.points.col(i));
        map_tags.push_back(static_cast<int>(k));
      }
    }
    const PlaneMap map(std::move(map_points), std::move(map_tags), map_options);

    // 3. The problem: IMU factors between keyframes, point-to-plane factors per sweep.
    ceres::Problem::Options problem_options;
    problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    for (Keyframe& kf : *keyframes) {
      problem.AddParameterBlock(kf.q_W_I.coeffs().data(), 4, &quaternion_manifold);
    }
    problem.AddParameterBlock(calibration->q_I_L.coeffs().data(), 4, &quaternion_manifold);
    sensors::PreintegrationOptions preintegration_options;
    preintegration_options.gravity_m_s2 = options.gravity_m_s2;
    for (size_t k = 0; k + 1 < keyframes->size(); ++k) {
      Keyframe& a = (*keyframes)[k];
      Keyframe& b = (*keyframes)[k + 1];
      sensors::ImuPreintegration pim(options.imu_noise, preintegration_options, a.b_g, a.b_a);
      pim.Integrate(imu, a.t_ns, b.t_ns);
      problem.AddResidualBlock(factors::ImuFactor::Create(pim), nullptr, a.q_W_I.coeffs().data(),
                               a.p_W_I.data(), a.v_W_I.data(), a.b_g.data(), a.b_a.data(),
                               b.q_W_I.coeffs().data(), b.p_W_I.data(), b.v_W_I.data(),
                               b.b_g.data(), b.b_a.data());
    }
    ceres::LossFunction* loss =
        options.cauchy_scale > 0.0 ? new ceres::CauchyLoss(options.cauchy_scale) : nullptr;
    std::vector<ceres::ResidualBlockId> point_blocks;
    for (size_t k = 0; k < sweeps.size(); ++k) {
      Keyframe& kf = (*keyframes)[k];
      for (int i : selection[k].residual_points) {
        factors::PointToPlaneMeasurement m;
        m.p_L = sweeps[k].cloud.points.col(i);
        m.motion = motion_of(k, i);
        if (!map.FindPlane(PointInWorld(kf, m.motion, g_W, calibration->q_I_L, calibration->p_I_L,
                                        m.p_L),
                           static_cast<int>(k), &m.plane)) {
          continue;
        }
        m.sigma_m = point_sigma_m;
        m.offset_linearization_s = offset_lin;
        point_blocks.push_back(problem.AddResidualBlock(
            new factors::PointToPlaneFactor(m, g_W), loss, kf.q_W_I.coeffs().data(),
            kf.p_W_I.data(), kf.v_W_I.data(), calibration->q_I_L.coeffs().data(),
            calibration->p_I_L.data(), offset));
      }
    }
    if (point_blocks.empty()) {
      delete loss;  // owned by the problem only once a residual block uses it
      throw Error("SolveLidarInertialBatch: no point found a plane");
    }

    // Gauge: the first pose is held (position and yaw are unobservable).
    problem.SetParameterBlockConstant((*keyframes)[0].q_W_I.coeffs().data());
    problem.SetParameterBlockConstant((*keyframes)[0].p_W_I.data());
    if (!options.estimate_extrinsic_rotation) {
      problem.SetParameterBlockConstant(calibration->q_I_L.coeffs().data());
    }
    if (!options.estimate_extrinsic_translation) {
      problem.SetParameterBlockConstant(calibration->p_I_L.data());
    }
    if (!options.estimate_time_offset) problem.SetParameterBlockConstant(offset);

    // 4. Solve.
    ceres::Solver::Options solver_options;
    solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    solver_options.max_num_iterations = options.solver_iterations;
    solver_options.num_threads = options.num_threads;
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
    if (!summary.IsSolutionUsable()) {
      throw Error("SolveLidarInertialBatch: the solver failed: " + summary.message);
    }

    // 5. Point residual statistics without the robust loss.
    ceres::Problem::EvaluateOptions evaluate;
    evaluate.residual_blocks = point_blocks;
    evaluate.apply_loss_function = false;
    std::vector<double> residuals;
    problem.Evaluate(evaluate, nullptr, &residuals, nullptr, nullptr);
    double sum_sq = 0.0;
    for (double r : residuals) sum_sq += r * r;
    report.point_rms_m =
        point_sigma_m * std::sqrt(sum_sq / static_cast<double>(residuals.size()));
    report.associated_points = static_cast<int>(point_blocks.size());
    report.final_cost = summary.final_cost;
    report.outer_iterations = iteration + 1;
    report.calibration_per_iteration.push_back(*calibration);

    const bool converged =
        geometry::AngularDistance(before.q_I_L, calibration->q_I_L) * 180.0 / M_PI <
            options.converged_rotation_deg &&
        (before.p_I_L - calibration->p_I_L).norm() < options.converged_translation_m &&
        std::abs(before.time_offset_lidar_imu_s - calibration->time_offset_lidar_imu_s) <
            options.converged_time_offset_s;
    if (converged && iteration >= options.coarse_to_fine_steps) break;
  }
  return report;
}

}  // namespace estimation
}  // namespace autocal
