#include "autocal/estimation/lidar_inertial_batch.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/parallel_for.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/estimation/keyframe_solver_options.h"
#include "autocal/factors/loss.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/factors/point_to_sweep_plane_factor.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "autocal/factors/prior_factors.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/se3.h"
#include "autocal/geometry/so3.h"
#include "estimation/outer_convergence.h"
#include "estimation/rotation_search.h"
#include "estimation/sweep_pairing.h"

namespace autocal {
namespace estimation {

namespace {

using internal::Association;
using internal::SweepsAtEstimate;
using internal::SweepSelection;

// The inputs of the solve and what every outer iteration shares.
struct BatchInputs {
  const sensors::ImuSamples& imu;
  const std::vector<SelectedSweep>& sweeps;
  std::vector<Keyframe>* keyframes;
  sensors::Calibration* calibration;
  const LidarInertialBatchOptions& options;
  Eigen::Vector3d g_W;

  int num_sweeps() const { return static_cast<int>(sweeps.size()); }
  // Runs body(k) for every sweep, on options.num_threads threads.
  void ForEachSweep(const std::function<void(size_t)>& body) const {
    ParallelFor(0, num_sweeps(), options.num_threads, [&](int64_t begin, int64_t end, int) {
      for (int64_t k = begin; k < end; ++k) body(static_cast<size_t>(k));
    });
  }
};

// 1-sigma of the gauge prior on the first keyframe's yaw: a direction no factor informs, so
// any weight fixes it without pulling on the data.
constexpr double kGaugeYawSigmaRad = 1e-6;

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
          report->covariance(rows_a[i], rows_b[j]) =
              c(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j));
        }
      }
    }
  }
  report->covariance_ok = true;
}

// One residual block per pair of sweeps (Eq. P9).
struct PointGroup {
  const factors::PointToSweepPlaneGroupFactor* factor;  // owned by the problem
  std::vector<double*> parameters;
};

// Where the outer loop stands (docs/estimation.md, "Coarse to fine", "The points' sigma"):
// the coarse level (planes 2^level times thicker, points that much farther and noisier than
// options.pairing; 0: fine) and the points' sigma of the fine iterations.
struct Schedule {
  int coarse_level;
  double fine_point_sigma_m;
  // The last iteration's step when it was fine and left the points' sigma settled: the next
  // iteration then solves the same problem (the same level and sigma), a step of the same
  // fixed-point map.
  std::optional<internal::OuterStep> step_of_settled_map;
};

PairingOptions PairingAt(const LidarInertialBatchOptions& options, const Schedule& schedule) {
  if (schedule.coarse_level > 0) {
    return internal::CoarsePairing(options.pairing, std::pow(2.0, schedule.coarse_level));
  }
  PairingOptions fine = options.pairing;
  fine.point_sigma_m = schedule.fine_point_sigma_m;
  if (options.plane_thickness_sigmas > 0.0) {  // Eq. P10b
    fine.plane_map.max_plane_thickness_m =
        std::min(fine.plane_map.max_plane_thickness_m,
                 options.plane_thickness_sigmas * schedule.fine_point_sigma_m);
  }
  return fine;
}

// The points' sigma from their distances (docs/estimation.md, "The points' sigma"): the RMS
// of those within the gate, or `previous_m` when none is or all lie on their planes exactly
// (a zero sigma would make every weight infinite).
double PointSigmaFromResiduals(const std::vector<double>& residuals_m, double gate_m,
                               double previous_m) {
  double sum_sq = 0.0;
  int64_t count = 0;
  for (double r : residuals_m) {
    if (std::abs(r) > gate_m) continue;
    sum_sq += r * r;
    ++count;
  }
  return sum_sq > 0.0 ? std::sqrt(sum_sq / static_cast<double>(count)) : previous_m;
}

// The coarsest level the distances within `gate_m` still need (Eq. P11): the smallest k >= 0
// whose gate fine_gate_m 2^k holds three robust sigmas of them (1.4826 times the median
// |distance|, blind to the wrong pairs a wide gate lets in).
int LevelFitting(const std::vector<double>& residuals_m, double gate_m, double fine_gate_m) {
  std::vector<double> within;
  within.reserve(residuals_m.size());
  for (double r : residuals_m) {
    if (std::abs(r) <= gate_m) within.push_back(std::abs(r));
  }
  if (within.empty()) return std::numeric_limits<int>::max();
  const auto middle = within.begin() + static_cast<std::ptrdiff_t>(within.size() / 2);
  std::nth_element(within.begin(), middle, within.end());
  const double reach_m = 3.0 * 1.4826 * *middle;
  int level = 0;
  while (fine_gate_m * std::pow(2.0, level) < reach_m && level < 30) ++level;
  return level;
}

// Moves the schedule on after an iteration with `used`: one coarse level down at least, to
// the level its distances need (LevelFitting) when that is finer, and the fine iterations'
// sigma from the distances. Returns whether the points' sigma had settled (always when it is
// fixed).
bool Advance(const LidarInertialBatchOptions& options, const std::vector<double>& residuals_m,
             const PairingOptions& used, Schedule* schedule) {
  if (schedule->coarse_level > 0) {
    schedule->coarse_level = std::min(
        schedule->coarse_level - 1,
        LevelFitting(residuals_m, used.max_point_to_plane_m, options.pairing.max_point_to_plane_m));
  }
  if (!options.point_sigma_from_residuals) return true;
  schedule->fine_point_sigma_m = PointSigmaFromResiduals(
      residuals_m, options.pairing.max_point_to_plane_m, schedule->fine_point_sigma_m);
  return std::abs(schedule->fine_point_sigma_m - used.point_sigma_m) <=
         options.converged_point_sigma_ratio * used.point_sigma_m;
}

BatchInputs Inputs(const sensors::ImuSamples& imu, const std::vector<SelectedSweep>& sweeps,
                   std::vector<Keyframe>* keyframes, sensors::Calibration* calibration,
                   const LidarInertialBatchOptions& options) {
  if (keyframes->size() != sweeps.size() || sweeps.size() < 2) {
    throw Error("SolveLidarInertialBatch: need one keyframe per sweep and at least two sweeps");
  }
  return BatchInputs{imu,         sweeps,  keyframes,
                     calibration, options, Eigen::Vector3d(0.0, 0.0, -options.gravity_m_s2)};
}

// A time offset the drive does not determine can wander during the solve until a sweep's points
// lie before the log's first IMU sample or past its last: the solve cannot place the sweep, and
// names the offset that took it there. [begin_ns, end_ns] is the sweep's motion table
// (SelectedSweep::TableInterval).
void CheckSweepMotionCovered(const BatchInputs& in, int64_t begin_ns, int64_t end_ns) {
  if (in.imu.size() < 2) throw Error("SolveLidarInertialBatch: the IMU log holds no interval");
  const auto fail = [&](const std::string& what) {
    throw Error("SolveLidarInertialBatch: at a LiDAR-IMU time offset of " +
                FormatFixed(1e3 * in.calibration->time_offset_lidar_imu_s, 1) + " ms " + what +
                "; a drive that does not determine the offset lets it wander there: fix it or "
                "give it a tighter prior in the problem file");
  };
  if (begin_ns < in.imu.front().t_ns) {
    fail("a sweep needs IMU samples before the log's first (" +
         FormatFixed(1e3 * NsToSeconds(in.imu.front().t_ns - begin_ns), 1) + " ms before them)");
  }
  if (end_ns > in.imu.back().t_ns) {
    fail("a sweep's points need IMU samples the log does not have (" +
         FormatFixed(1e3 * NsToSeconds(end_ns - in.imu.back().t_ns), 1) + " ms beyond them)");
  }
}

// Step 1: every sweep propagated with the current estimate.
SweepsAtEstimate PropagateSweeps(const BatchInputs& in) {
  const size_t n = in.sweeps.size();
  const double offset_lin = in.calibration->time_offset_lidar_imu_s;
  SweepsAtEstimate out;
  out.sweeps = &in.sweeps;
  out.keyframes = in.keyframes;
  out.calibration = in.calibration;
  out.g_W = in.g_W;
  out.tables.resize(n);
  out.reference_motion.resize(n);
  out.T_W_L.resize(n);
  in.ForEachSweep([&](size_t k) {
    const Keyframe& kf = (*in.keyframes)[k];
    const SelectedSweep& s = in.sweeps[k];
    const ImuInterval table = s.TableInterval(offset_lin, kf.t_ns);
    CheckSweepMotionCovered(in, table.begin_ns, table.end_ns);
    // The offset's rate: the mean over a sweep's span about each point (Eq. P1b).
    out.tables[k].emplace(in.imu, table.begin_ns, table.end_ns, kf.b_g, kf.b_a,
                          SecondsToNs(s.span.length_s()), kf.t_ns);
    out.reference_motion[k] = out.tables[k]->At(in.sweeps[k].t_ns + SecondsToNs(offset_lin));
    out.T_W_L[k] = internal::SweepLidarPose(kf, out.reference_motion[k], in.g_W,
                                            in.calibration->q_I_L, in.calibration->p_I_L);
  });
  return out;
}

// Step 4, the points: the points of sweep k on planes of sweep j share every parameter block
// (Eq. P9); the robust loss acts per point inside the factor. Returns the points associated.
int AddPointGroups(const BatchInputs& in, std::vector<std::vector<Association>> associations,
                   ceres::Problem* problem, std::vector<PointGroup>* point_groups) {
  std::vector<Keyframe>& keyframes = *in.keyframes;
  sensors::Calibration* calibration = in.calibration;
  int associated_points = 0;
  for (int k = 0; k < in.num_sweeps(); ++k) {
    Keyframe& kf = keyframes[static_cast<size_t>(k)];
    std::map<int, std::vector<factors::PointToSweepPlaneMeasurement>> by_partner;
    for (const Association& a : associations[static_cast<size_t>(k)]) {
      by_partner[a.partner].push_back(a.measurement);
    }
    // Each sweep's associations go once copied: they and the factors never coexist whole.
    std::vector<Association>().swap(associations[static_cast<size_t>(k)]);
    for (const auto& [partner, measurements] : by_partner) {
      Keyframe& kf_j = keyframes[static_cast<size_t>(partner)];
      PointGroup group;
      group.parameters = {kf.q_W_I.coeffs().data(),
                          kf.p_W_I.data(),
                          kf.v_W_I.data(),
                          kf_j.q_W_I.coeffs().data(),
                          kf_j.p_W_I.data(),
                          kf_j.v_W_I.data(),
                          calibration->q_I_L.coeffs().data(),
                          calibration->p_I_L.data(),
                          &calibration->time_offset_lidar_imu_s};
      auto factor = std::make_unique<factors::PointToSweepPlaneGroupFactor>(measurements, in.g_W,
                                                                            in.options.point_loss);
      group.factor = factor.get();
      problem->AddResidualBlock(factor.release(), nullptr, group.parameters);
      point_groups->push_back(std::move(group));
      associated_points += static_cast<int>(measurements.size());
    }
  }
  if (point_groups->empty()) throw Error("SolveLidarInertialBatch: no point found a plane");
  return associated_points;
}

// Step 4, the gauge and the held blocks. Position and yaw are unobservable from IMU and LiDAR
// alone; roll and pitch are not (gravity) and stay free, or the initializer's tilt error would
// be frozen in and leak gravity into every acceleration. The yaw is held by a prior on the
// first keyframe's rotation about z_W only: for the right perturbation phi, the rotation in W
// is R0 phi, so the prior's one nonzero row is z_W^T R0 / sigma. Returns the held axes of
// p_I_L.
std::vector<int> HoldGaugeAndBlocks(const BatchInputs& in, ceres::Problem* problem) {
  const LidarInertialBatchOptions& options = in.options;
  sensors::Calibration* calibration = in.calibration;
  if (options.hold_first_pose) {
    Keyframe& first = (*in.keyframes)[0];
    problem->SetParameterBlockConstant(first.p_W_I.data());
    Eigen::Matrix3d yaw_only = Eigen::Matrix3d::Zero();
    yaw_only.row(2) = first.q_W_I.normalized().toRotationMatrix().row(2) / kGaugeYawSigmaRad;
    problem->AddResidualBlock(new factors::QuaternionPriorFactor(first.q_W_I, yaw_only), nullptr,
                              first.q_W_I.coeffs().data());
  }
  if (!options.estimate.extrinsic_rotation) {
    problem->SetParameterBlockConstant(calibration->q_I_L.coeffs().data());
  }
  std::vector<int> held_axes;
  for (int axis = 0; axis < 3; ++axis) {
    if (options.hold_p_I_L_axes(axis)) held_axes.push_back(axis);
  }
  if (!options.estimate.extrinsic_translation || held_axes.size() == 3) {
    problem->SetParameterBlockConstant(calibration->p_I_L.data());
  } else if (!held_axes.empty()) {
    problem->SetManifold(calibration->p_I_L.data(), new ceres::SubsetManifold(3, held_axes));
  }
  if (!options.estimate.time_offset) {
    problem->SetParameterBlockConstant(&calibration->time_offset_lidar_imu_s);
  }
  return held_axes;
}

// Signed point-to-plane distances (m) without the robust loss.
std::vector<double> PointDistances(const std::vector<PointGroup>& point_groups,
                                   int associated_points, double point_sigma_m) {
  std::vector<double> residuals(static_cast<size_t>(associated_points));
  double* out = residuals.data();
  for (const PointGroup& group : point_groups) {
    group.factor->WhitenedDistances(group.parameters.data(), out);
    out += group.factor->num_points();
  }
  for (double& r : residuals) r *= point_sigma_m;
  return residuals;
}

// Step 5: Ceres on the iteration's problem.
ceres::Solver::Summary SolveProblem(const LidarInertialBatchOptions& options,
                                    ceres::Problem* problem) {
  const ceres::Solver::Options solver_options =
      KeyframeSolverOptions(options.solver_iterations, options.num_threads);
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, problem, &summary);
  if (!summary.IsSolutionUsable()) {
    throw Error("SolveLidarInertialBatch: the solver failed: " + summary.message);
  }
  return summary;
}

// The points the loss down-weights at `sigma_m` (factors::DownweightedByLoss) and the others'
// RMS distance.
void RecordDownweightedPoints(const std::vector<double>& residuals_m, double sigma_m,
                              const factors::LossOptions& loss, LidarInertialBatchReport* report) {
  const std::unique_ptr<ceres::LossFunction> rho(factors::MakeLossFunction(loss));
  int downweighted = 0;
  double sum_sq = 0.0;
  for (double r : residuals_m) {
    if (factors::DownweightedByLoss(rho.get(), r * r / (sigma_m * sigma_m))) {
      ++downweighted;
    } else {
      sum_sq += r * r;
    }
  }
  const size_t kept = residuals_m.size() - static_cast<size_t>(downweighted);
  report->points_downweighted_by_loss = downweighted;
  report->point_rms_not_downweighted_m =
      kept == 0 ? 0.0 : std::sqrt(sum_sq / static_cast<double>(kept));
}

double SecondsBetween(std::chrono::steady_clock::time_point a,
                      std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// One outer iteration: propagate, build the maps, associate, build the problem and solve it
// (steps 1-6), then move the schedule on (Advance). Returns whether it was the last.
bool OuterIteration(const BatchInputs& in, int iteration,
                    std::chrono::steady_clock::time_point start, Schedule* schedule,
                    LidarInertialBatchReport* report) {
  const LidarInertialBatchOptions& options = in.options;
  sensors::Calibration* calibration = in.calibration;
  const sensors::Calibration before = *calibration;
  const auto iteration_start = std::chrono::steady_clock::now();
  const int level = schedule->coarse_level;
  const bool fine = level == 0;
  const PairingOptions pairing = PairingAt(options, *schedule);

  // 4. The problem: IMU factors between keyframes, point-to-plane factors per pair of sweeps.
  geometry::RightQuaternionManifold quaternion_manifold;
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  for (Keyframe& kf : *in.keyframes) {
    problem.AddParameterBlock(kf.q_W_I.coeffs().data(), 4, &quaternion_manifold);
  }
  problem.AddParameterBlock(calibration->q_I_L.coeffs().data(), 4, &quaternion_manifold);
  KeyframeImuOptions imu_options;
  imu_options.noise = options.imu_noise;
  imu_options.gravity_m_s2 = options.gravity_m_s2;
  imu_options.num_threads = options.num_threads;
  AddImuFactors(&problem, in.imu, in.keyframes, imu_options);
  std::vector<PointGroup> point_groups;
  // The associations (and the maps before them) go once the factors hold the measurements: a
  // long log's maps, associations and problem need not share the memory.
  const int associated_points =
      AddPointGroups(in,
                     internal::PairEverySweep(PropagateSweeps(in), pairing,
                                              options.map_neighbor_sweeps, options.num_threads),
                     &problem, &point_groups);
  // Other sensors' factors and priors, from the caller.
  if (options.add_factors) options.add_factors(&problem, in.keyframes, calibration);
  const std::vector<int> held_axes = HoldGaugeAndBlocks(in, &problem);
  if (iteration == 0) {
    report->initial_point_residuals_m =
        PointDistances(point_groups, associated_points, pairing.point_sigma_m);
  }

  // 5. Solve.
  const auto solve_start = std::chrono::steady_clock::now();
  report->seconds_association += SecondsBetween(iteration_start, solve_start);
  const ceres::Solver::Summary summary = SolveProblem(options, &problem);
  report->seconds_solver += SecondsBetween(solve_start, std::chrono::steady_clock::now());

  // 6. Point residual statistics without the robust loss.
  const std::vector<double> residuals =
      PointDistances(point_groups, associated_points, pairing.point_sigma_m);
  double sum_sq = 0.0;
  for (double r : residuals) sum_sq += r * r;
  report->final_point_residuals_m = residuals;
  report->point_rms_m = std::sqrt(sum_sq / static_cast<double>(residuals.size()));
  report->point_sigma_m = pairing.point_sigma_m;
  RecordDownweightedPoints(residuals, pairing.point_sigma_m, options.point_loss, report);
  const bool sigma_settled = Advance(options, residuals, pairing, schedule);
  report->associated_points = associated_points;
  report->final_cost = summary.final_cost;
  report->outer_iterations = iteration + 1;
  report->calibration_per_iteration.push_back(*calibration);
  report->coarse_level_per_iteration.push_back(level);
  if (options.progress) {
    LidarInertialBatchProgress progress;
    progress.iteration = iteration + 1;
    progress.max_iterations = options.outer_iterations;
    progress.cost = summary.final_cost;
    progress.elapsed_s = SecondsBetween(start, std::chrono::steady_clock::now());
    progress.associated_points = report->associated_points;
    options.progress(progress);
  }
  report->termination = summary.message;

  const internal::OuterStep step = internal::StepBetween(before, *calibration);
  report->converged = internal::OuterLoopConverged(options, step, schedule->step_of_settled_map) &&
                      sigma_settled && fine;
  schedule->step_of_settled_map =
      fine && sigma_settled ? std::optional<internal::OuterStep>(step) : std::nullopt;
  const bool last = report->converged || iteration + 1 == options.outer_iterations;
  if (last && options.compute_covariance) {
    ComputeCovariance(&problem, calibration, held_axes, report);
  }
  if (last && options.inspect_final_problem) options.inspect_final_problem(&problem);
  return last;
}

}  // namespace

SelectedSweep SelectForBatch(const lidar::LidarSweep& sweep, const PairingOptions& pairing) {
  const lidar::PointCloud& cloud = sweep.cloud;
  if (cloud.empty()) throw Error("SolveLidarInertialBatch: the sweep holds no points");
  if (!cloud.has_time()) throw Error("SolveLidarInertialBatch: sweeps need per-point time");
  const SweepSelection selection = internal::SelectSweepPoints(cloud, pairing);
  // The union of both selections in sweep order, and each index remapped into it.
  std::vector<int> kept(selection.residual_points);
  kept.insert(kept.end(), selection.map_points.begin(), selection.map_points.end());
  std::sort(kept.begin(), kept.end());
  kept.erase(std::unique(kept.begin(), kept.end()), kept.end());
  const auto remapped = [&](const std::vector<int>& indices) {
    std::vector<int> out(indices.size());
    for (size_t i = 0; i < indices.size(); ++i) {
      out[i] =
          static_cast<int>(std::lower_bound(kept.begin(), kept.end(), indices[i]) - kept.begin());
    }
    return out;
  };
  SelectedSweep out;
  out.t_ns = sweep.t_ns;
  out.span = SpanOf(sweep);
  out.points.resize(3, static_cast<Eigen::Index>(kept.size()));
  out.time_s.resize(static_cast<Eigen::Index>(kept.size()));
  for (size_t i = 0; i < kept.size(); ++i) {
    out.points.col(static_cast<Eigen::Index>(i)) = cloud.points.col(kept[i]).cast<float>();
    out.time_s(static_cast<Eigen::Index>(i)) = static_cast<float>(cloud.time_s(kept[i]));
  }
  out.residual_points = remapped(selection.residual_points);
  out.map_points = remapped(selection.map_points);
  return out;
}

LidarInertialBatchReport SolveLidarInertialBatch(const sensors::ImuSamples& imu,
                                                 const std::vector<lidar::LidarSweep>& sweeps,
                                                 std::vector<Keyframe>* keyframes,
                                                 sensors::Calibration* calibration,
                                                 const LidarInertialBatchOptions& options) {
  std::vector<SelectedSweep> selected(sweeps.size());
  ParallelFor(0, static_cast<int64_t>(sweeps.size()), options.num_threads,
              [&](int64_t begin, int64_t end, int) {
                for (int64_t k = begin; k < end; ++k) {
                  selected[static_cast<size_t>(k)] =
                      SelectForBatch(sweeps[static_cast<size_t>(k)], options.pairing);
                }
              });
  return SolveLidarInertialBatch(imu, selected, keyframes, calibration, options);
}

LidarInertialBatchReport SolveLidarInertialBatch(const sensors::ImuSamples& imu,
                                                 const std::vector<SelectedSweep>& sweeps,
                                                 std::vector<Keyframe>* keyframes,
                                                 sensors::Calibration* calibration,
                                                 const LidarInertialBatchOptions& options) {
  const BatchInputs in = Inputs(imu, sweeps, keyframes, calibration, options);
  LidarInertialBatchReport report;
  const auto start = std::chrono::steady_clock::now();
  if (options.starting_rotation_search_deg > 0.0 && options.estimate.extrinsic_rotation) {
    internal::RotationSearchOptions search;
    search.range_rad = options.starting_rotation_search_deg * kDegToRad;
    search.num_threads = options.num_threads;
    report.rotation_search = internal::SearchStartingRotation(imu, sweeps, *keyframes, *calibration,
                                                              in.g_W, options.pairing, search);
    calibration->q_I_L = report.rotation_search.q_I_L_start;
  }
  Schedule schedule{std::max(0, options.coarse_to_fine_steps), options.pairing.point_sigma_m,
                    std::nullopt};
  for (int iteration = 0; iteration < options.outer_iterations; ++iteration) {
    if (OuterIteration(in, iteration, start, &schedule, &report)) break;
  }
  return report;
}

}  // namespace estimation
}  // namespace autocal
