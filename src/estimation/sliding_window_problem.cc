// The window problem of the sliding window (docs/sliding_window.md, "One update" steps 3-5):
// associating the points, building it, solving it, marginalizing its oldest keyframe and its
// calibration covariance.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"
#include "autocal/common/time.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/estimation/sliding_window.h"
#include "autocal/factors/imu_factor.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "autocal/geometry/se3.h"
#include "autocal/geometry/so3.h"
#include "estimation/firing_poses.h"
#include "estimation/normal_equations.h"
#include "estimation/sliding_window_internal.h"
#include "estimation/window_solver.h"
#include "factors/point_group_storage.h"

namespace autocal {
namespace estimation {

using internal::AttachedFactor;
using internal::StateBlocks;

namespace {

// A keyframe's LiDAR pose T_W_I T_I_L, its IMU pose moved by dt_s at its velocity and at the
// angular rate w_I (Eq. W6).
geometry::Pose3d LidarPose(const SlidingWindowState& x, const sensors::Calibration& c,
                           const Eigen::Vector3d& w_I, double dt_s) {
  const Eigen::Quaterniond q_W_I = x.q_W_I * geometry::Exp(Eigen::Vector3d(w_I * dt_s));
  return geometry::Pose3d(q_W_I * c.q_I_L, x.p_W_I + x.v_W_I * dt_s + q_W_I * c.p_I_L);
}

}  // namespace

// Step 3 (docs/sliding_window.md, "Pairing points with planes" and "Reuse between updates"): the
// window's sweeps paired by the pairing engine, which keeps their maps, tries and groups between
// updates.
void SlidingWindowEstimator::Impl::AssociatePoints() {
  std::vector<internal::PairingSweep> sweeps;
  for (const auto& kf : window_) {
    if (!kf->sweep) continue;
    sweeps.push_back({kf->id, &kf->state, &*kf->sweep, kf->sweep_span, &kf->residuals,
                      &kf->map_points, &kf->map, &kf->pairing, &kf->point_groups});
  }
  internal::PairingUpdate update;
  update.imu = &imu_;
  update.g_W = g_W_;
  update.calibration = &calibration_;
  update.recent_rotation_rad =
      recent_q_I_L_.empty() ? 0.0
                            : geometry::AngularDistance(recent_q_I_L_.front(), calibration_.q_I_L);
  update.full_history = static_cast<int>(recent_q_I_L_.size()) >= options_.window_size;
  const internal::PairingResult result = pairing_.Pair(sweeps, update);
  timing_.extrinsic_settled = result.extrinsic_settled;
  timing_.plane_lookups += result.plane_lookups;
}

std::unique_ptr<SlidingWindowEstimator::Impl::ProblemBuild>
SlidingWindowEstimator::Impl::BuildProblem(const std::vector<double>* group_motions) {
  auto build = std::make_unique<ProblemBuild>();
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  build->problem = std::make_unique<ceres::Problem>(problem_options);
  ceres::Problem& problem = *build->problem;
  geometry::RightQuaternionManifold* manifold = &quaternion_manifold_;

  for (const auto& kf : window_) {
    std::vector<double*> blocks = StateBlocks(&kf->state);
    problem.AddParameterBlock(blocks[0], 4, manifold);
    for (size_t i = 1; i < blocks.size(); ++i) problem.AddParameterBlock(blocks[i], 3);
  }
  for (const internal::CalibrationBlock& b :
       internal::CalibrationBlocks(&calibration_, options_.estimate)) {
    problem.AddParameterBlock(b.values, b.ambient_size,
                              b.ambient_size != b.tangent_size ? manifold : nullptr);
    if (!b.estimated) problem.SetParameterBlockConstant(b.values);
  }

  const bool linearize = options_.linearization.passes_per_update > 0;
  const auto relinearized = [&build, linearize](ceres::ResidualBlockId id, bool always) {
    if (always || !linearize) build->relinearized.push_back(id);
  };
  const auto add = [&problem, &build, linearize, &relinearized](const AttachedFactor& f) {
    if (linearize && f.linearized_per_pass != nullptr) {
      // Its loss's weight is held for the pass (Eq. W4).
      build->owned.push_back(std::make_unique<internal::LinearizedCost<>>(
          *f.cost, f.blocks, f.linearized_per_pass, f.loss));
      relinearized(problem.AddResidualBlock(build->owned.back().get(), nullptr, f.blocks), false);
      return;
    }
    relinearized(problem.AddResidualBlock(f.cost.get(), f.loss, f.blocks), f.loss != nullptr);
  };
  for (const AttachedFactor& f : calibration_priors_) add(f);
  for (size_t k = 0; k < window_.size(); ++k) {
    WindowKeyframe& kf = *window_[k];
    for (const AttachedFactor& f : kf.factors) add(f);
    if (k == 0) continue;
    build->owned.emplace_back(factors::ImuFactor::Create(*kf.imu_from_previous));
    std::vector<double*> blocks = StateBlocks(&window_[k - 1]->state);
    for (double* b : StateBlocks(&kf.state)) blocks.push_back(b);
    relinearized(problem.AddResidualBlock(build->owned.back().get(), imu_loss_.get(), blocks),
                 true);
  }
  if (prior_) {
    relinearized(problem.AddResidualBlock(prior_.get(), nullptr, prior_->parameter_pointers()),
                 false);
  }
  AddPointGroups(build.get(), group_motions);
  return build;
}

// The point groups carry the LiDAR loss themselves (Eq. P9); in a later pass each keeps its
// linearization while its sweeps stay within relinearization_tolerance_m of it (Eq. W6).
void SlidingWindowEstimator::Impl::AddPointGroups(ProblemBuild* build,
                                                  const std::vector<double>* group_motions) {
  ceres::Problem& problem = *build->problem;
  const bool linearize = options_.linearization.passes_per_update > 0;
  const double tolerance_m = options_.linearization.relinearization_tolerance_m;
  std::map<int, const WindowKeyframe*> keyframe_of_id;
  for (const auto& kf : window_) keyframe_of_id[kf->id] = kf.get();
  size_t index = 0;
  for (const auto& kf : window_) {
    for (internal::SweepPointGroup& g : kf->point_groups) {
      if (!linearize) {
        build->relinearized.push_back(
            problem.AddResidualBlock(g.solver_cost(), nullptr, g.parameters));
        continue;
      }
      const bool moved = group_motions == nullptr || !((*group_motions)[index++] <= tolerance_m);
      if (moved) {
        const SlidingWindowState& y = keyframe_of_id.at(g.partner_id)->state;
        internal::SweepPointGroup::Linearization& l = g.linearization.emplace();
        l.cost = internal::LinearizePointGroup(g.factor.get(), g.parameters);
        l.T_W_Lk = LidarPose(kf->state, calibration_, Eigen::Vector3d::Zero(), 0.0);
        l.T_W_Lj = LidarPose(y, calibration_, Eigen::Vector3d::Zero(), 0.0);
        l.v_W_Ik = kf->state.v_W_I;
        l.v_W_Ij = y.v_W_I;
        l.offset_s = calibration_.time_offset_lidar_imu_s;
      }
      problem.AddResidualBlock(g.linearization->cost.get(), nullptr, g.parameters);
    }
  }
}

double SlidingWindowEstimator::Impl::SquaredPointDistances(bool oldest_only) const {
  const int oldest_id = window_.front()->id;
  double sum = 0.0;
  std::vector<double> distances;
  for (const auto& kf : window_) {
    for (const internal::SweepPointGroup& g : kf->point_groups) {
      if (oldest_only && kf->id != oldest_id && g.partner_id != oldest_id) continue;
      distances.resize(static_cast<size_t>(g.factor->num_points()));
      g.factor->WhitenedDistances(g.parameters.data(), distances.data());
      for (double r : distances) sum += r * r;
    }
  }
  return sum * options_.pairing.point_sigma_m * options_.pairing.point_sigma_m;
}

double SlidingWindowEstimator::Impl::last_point_rms_m() const {
  if (!last_point_rms_m_) {
    last_point_rms_m_ = last_associated_points_ == 0
                            ? 0.0
                            : std::sqrt((dropped_point_squared_m2_ + SquaredPointDistances(false)) /
                                        static_cast<double>(last_associated_points_));
  }
  return *last_point_rms_m_;
}

// Eq. W6: how far each point group's points moved since the group was linearized: its two
// sweeps' relative motion, bounded as in Eq. W1 at the range of the keyframe's farthest
// residual point, plus the change of each sweep's deskew (its velocity's change times the
// time from its stamp to its farthest point, SweepSpan::reach_s). A sweep's LiDAR pose is T_W_I
// T_I_L at its keyframe, moved by the change of the time offset since at the keyframe's velocity
// and at its mean angular rate over the interval from the previous keyframe (to the next, for the
// oldest).
std::vector<double> SlidingWindowEstimator::Impl::PointGroupMotions() const {
  const size_t n = window_.size();
  std::vector<Eigen::Vector3d> rates_I(n, Eigen::Vector3d::Zero());
  std::map<int, size_t> position_of_id;
  for (size_t k = 0; k < n; ++k) {
    position_of_id[window_[k]->id] = k;
    if (n < 2) continue;
    const SlidingWindowState& x = window_[k]->state;
    const SlidingWindowState& y = window_[k > 0 ? k - 1 : 1]->state;
    const double dt_s = NsToSeconds(x.t_ns - y.t_ns);
    if (dt_s != 0.0) rates_I[k] = geometry::Log(y.q_W_I.conjugate() * x.q_W_I) / dt_s;
  }
  std::vector<double> motions;
  for (size_t k = 0; k < n; ++k) {
    const WindowKeyframe& kf = *window_[k];
    for (const internal::SweepPointGroup& g : kf.point_groups) {
      if (!g.linearization) {
        motions.push_back(std::numeric_limits<double>::infinity());
        continue;
      }
      const internal::SweepPointGroup::Linearization& l = *g.linearization;
      const size_t j = position_of_id.at(g.partner_id);
      const WindowKeyframe& partner = *window_[j];
      const double dt_s = calibration_.time_offset_lidar_imu_s - l.offset_s;
      const geometry::Pose3d T_W_Lk = LidarPose(kf.state, calibration_, rates_I[k], dt_s);
      const geometry::Pose3d T_W_Lj = LidarPose(partner.state, calibration_, rates_I[j], dt_s);
      // The deskew within each sweep moves a point by at most its velocity's change times its
      // time from the sweep's stamp.
      const double deskew_m =
          (kf.state.v_W_I - l.v_W_Ik).norm() * kf.sweep_span.reach_s() +
          (partner.state.v_W_I - l.v_W_Ij).norm() * partner.sweep_span.reach_s();
      motions.push_back(internal::MaxPointMotion(l.T_W_Lj.Inverse() * l.T_W_Lk,
                                                 T_W_Lj.Inverse() * T_W_Lk,
                                                 kf.residuals.max_range_m) +
                        deskew_m);
    }
  }
  return motions;
}

// With the points linearized per pass ("Linearized once per pass") the solve runs up to
// point_linearizations_per_update passes, each on the point groups relinearized where the previous
// pass ended, and stops early once no group's sweeps moved by more than relinearization_tolerance_m
// since its linearization (Eq. W6).
void SlidingWindowEstimator::Impl::Solve(std::unique_ptr<ProblemBuild>* build) {
  // The window's own Levenberg-Marquardt (Eq. W5): the rows fixed for the pass enter by
  // their normal equations, formed once; an iteration evaluates the IMU factors and the rows
  // with a loss and factors the dense system. It runs on one thread (docs/sliding_window.md,
  // "Options": num_threads).
  timing_.solver_iterations = 0;
  timing_.solver_passes = 0;
  const int max_passes = std::max(1, options_.linearization.passes_per_update);
  for (int pass = 0; pass < max_passes; ++pass) {
    const internal::WindowSolverSummary summary = internal::SolveWindowPass(
        (*build)->problem.get(), (*build)->relinearized, options_.solver, &solver_workspace_);
    timing_.solver_iterations += summary.iterations;
    ++timing_.solver_passes;
    for (auto& kf : window_) kf->state.q_W_I.normalize();
    if (pass + 1 == max_passes) break;
    // Tolerance 0: every group relinearized by every pass.
    std::optional<std::vector<double>> motions;
    if (options_.linearization.relinearization_tolerance_m > 0.0) {
      motions = PointGroupMotions();
      if (std::all_of(motions->begin(), motions->end(), [this](double m) {
            return m <= options_.linearization.relinearization_tolerance_m;
          })) {
        break;
      }
    }
    build->reset();  // it holds the linearizations the next build may replace
    *build = BuildProblem(motions ? &*motions : nullptr);
  }

  // The RMS of the distances is evaluated when asked for (last_point_rms_m).
  last_associated_points_ = 0;
  for (const auto& kf : window_) {
    for (const internal::SweepPointGroup& g : kf->point_groups) {
      last_associated_points_ += g.factor->num_points();
    }
  }
  dropped_point_squared_m2_ = 0.0;
  last_point_rms_m_.reset();
}

// Eq. M1-M3 over every factor touching the oldest keyframe: its prior or the previous
// marginalization prior, its IMU factor to the next keyframe, its wheel/GNSS factors and the
// point factors that pair its sweep with other window sweeps (either way round). The result
// replaces the previous prior, which it includes.
std::unique_ptr<MarginalizationPrior> SlidingWindowEstimator::Impl::MarginalizeOldest(
    ProblemBuild* build) {
  const std::vector<double*> blocks = StateBlocks(&window_.front()->state);
  if (prior_) {
    const std::vector<double*> kept = prior_->parameter_pointers();
    if (std::find(kept.begin(), kept.end(), blocks[0]) == kept.end()) {
      throw Error(
          "SlidingWindowEstimator: the marginalization prior does not reach the oldest "
          "keyframe");
    }
  }
  if (!options_.smoothing) {
    return Marginalize(build->problem.get(), blocks, options_.marginalization);
  }
  MarginalConditional conditional;
  std::unique_ptr<MarginalizationPrior> prior =
      Marginalize(build->problem.get(), blocks, options_.marginalization, &conditional);
  RecordSmoothingStep(std::move(conditional));
  return prior;
}

void SlidingWindowEstimator::Impl::SwapInTestedPrior(ceres::Problem* problem) const {
  if (prior_) {
    std::vector<ceres::ResidualBlockId> ids;
    problem->GetResidualBlocksForParameterBlock(prior_->parameter_pointers().front(), &ids);
    for (const ceres::ResidualBlockId id : ids) {
      if (problem->GetCostFunctionForResidualBlock(id) == prior_.get()) {
        problem->RemoveResidualBlock(id);
        break;
      }
    }
  }
  if (tested_prior_) {
    problem->AddResidualBlock(tested_prior_.get(), nullptr, tested_prior_->parameter_pointers());
  }
}

std::unique_ptr<MarginalizationPrior>
SlidingWindowEstimator::Impl::MarginalizeOldestWithTestedBlocks(ProblemBuild* build) {
  ceres::Problem* problem = build->problem.get();
  SwapInTestedPrior(problem);
  for (const sensors::CalibrationBlockId id : options_.tested_fixed_blocks) {
    double* values = sensors::CalibrationBlock(id).values(&calibration_);
    if (problem->HasParameterBlock(values)) problem->SetParameterBlockVariable(values);
  }
  return Marginalize(problem, StateBlocks(&window_.front()->state), options_.marginalization);
}

std::vector<FixedDirectionMove> SlidingWindowEstimator::Impl::FixedDirectionsTheStreamMoves(
    std::vector<EstimatedBlock> fixed, double max_sigmas) {
  std::vector<EstimatedBlock> tested;
  std::vector<size_t> index;  // each tested block's in `fixed`
  for (size_t b = 0; b < fixed.size(); ++b) {
    const std::vector<sensors::CalibrationBlockId>& ids = options_.tested_fixed_blocks;
    if (std::find(ids.begin(), ids.end(), fixed[b].id) == ids.end()) continue;
    fixed[b].data = sensors::CalibrationBlock(fixed[b].id).values(&calibration_);
    tested.push_back(std::move(fixed[b]));
    index.push_back(b);
  }
  if (tested.empty()) return {};
  if (!untested_reason_.empty()) {
    throw Error(
        "SlidingWindowEstimator: the fixed blocks could not be tested against the stream: " +
        untested_reason_);
  }
  const std::unique_ptr<ProblemBuild> build = BuildProblem();
  SwapInTestedPrior(build->problem.get());
  std::vector<FixedDirectionMove> moves =
      FixedDirectionsTheDataMove(tested, build->problem.get(), options_.num_threads, max_sigmas);
  for (FixedDirectionMove& move : moves) move.block = index[move.block];
  return moves;
}

CalibrationCovariance SlidingWindowEstimator::Impl::ComputeCalibrationCovariance(
    double min_reciprocal_condition_number) {
  const std::unique_ptr<ProblemBuild> build = BuildProblem();
  CalibrationCovariance out;
  std::vector<const double*> blocks;
  int size = 0;
  for (const internal::CalibrationBlock& b :
       internal::CalibrationBlocks(&calibration_, options_.estimate)) {
    if (!b.estimated) continue;
    out.names.push_back(b.name);
    out.offsets.push_back(size);
    blocks.push_back(b.values);
    size += b.tangent_size;
  }
  out.covariance = Eigen::MatrixXd::Zero(size, size);
  if (blocks.empty()) return out;

  out.covariance =
      internal::DenseBlockCovariance(build->problem.get(), blocks, min_reciprocal_condition_number,
                                     options_.num_threads, "SlidingWindowEstimator");
  return out;
}

}  // namespace estimation
}  // namespace autocal
