#include "estimation/rotation_search.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>

#include "autocal/common/parallel_for.h"
#include "autocal/common/units.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/geometry/so3.h"
#include "autocal/lidar/plane_map.h"
#include "estimation/sweep_pairing.h"

namespace autocal {
namespace estimation {
namespace internal {

namespace {

// The search scores at the solve's finest coarse level: gate, plane thickness and the
// points' sigma twice the fine ones.
constexpr double kSearchCoarseFactor = 2.0;
// Candidates a side at most; a wider range (a weak prior on keyframes tens of metres apart)
// takes a coarser step instead.
constexpr int kMaxStepsPerSide = 32;

struct Score {
  int paired = 0;      // points that found a plane within the gate
  double value = 0.0;  // each 1 - (distance / gate)^2
};

// Two consecutive keyframes' sweeps with their motion from their keyframes: the residual
// points of `k` are scored against the planes of `k + 1`.
struct ScoredPair {
  int k = 0;
  std::optional<ImuMotionTable> table_k, table_j;
};

// The motion table of sweep k, or none when the IMU does not cover it (the solve's own check
// then names the offset).
std::optional<ImuMotionTable> TableOf(const sensors::ImuSamples& imu, const SelectedSweep& sweep,
                                      const Keyframe& kf, double offset_s) {
  const ImuInterval table = sweep.TableInterval(offset_s, kf.t_ns);
  if (!ImuMotionTable::Covers(imu, table.begin_ns, table.end_ns)) return std::nullopt;
  return ImuMotionTable(imu, table.begin_ns, table.end_ns, kf.b_g, kf.b_a, 0, kf.t_ns);
}

class PairScore {
 public:
  PairScore(const sensors::ImuSamples& imu, const std::vector<SelectedSweep>& sweeps,
            const std::vector<Keyframe>& keyframes, const sensors::Calibration& calibration,
            const Eigen::Vector3d& g_W, const PairingOptions& pairing, int count, int num_threads)
      : sweeps_(sweeps),
        keyframes_(keyframes),
        calibration_(calibration),
        g_W_(g_W),
        pairing_(pairing),
        num_threads_(num_threads) {
    const int last = static_cast<int>(sweeps.size()) - 1;
    count = std::min(count, last);
    const double offset_s = calibration.time_offset_lidar_imu_s;
    for (int i = 0; i < count; ++i) {
      ScoredPair pair;
      pair.k = static_cast<int>(static_cast<int64_t>(i) * last / count);
      const size_t k = static_cast<size_t>(pair.k);
      pair.table_k = TableOf(imu, sweeps[k], keyframes[k], offset_s);
      pair.table_j = TableOf(imu, sweeps[k + 1], keyframes[k + 1], offset_s);
      // A pair the car did not move between scores the same at every rotation.
      const bool moved = Displacement(pair).norm() > pairing.max_point_to_plane_m;
      if (moved && pair.table_k && pair.table_j) pairs_.push_back(std::move(pair));
    }
  }

  // The median distance between the scored keyframes.
  double MedianSpacing() const {
    std::vector<double> d;
    for (const ScoredPair& pair : pairs_) d.push_back(Displacement(pair).norm());
    if (d.empty()) return 0.0;
    const auto middle = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
    std::nth_element(d.begin(), middle, d.end());
    return *middle;
  }

  // The direction of travel and the up direction across it, in the IMU frame (summed over
  // the scored pairs).
  void Axes(Eigen::Vector3d* travel_I, Eigen::Vector3d* across_up_I) const {
    Eigen::Vector3d travel = Eigen::Vector3d::Zero(), up = Eigen::Vector3d::Zero();
    for (const ScoredPair& pair : pairs_) {
      const Eigen::Quaterniond q_I_W = keyframes_[static_cast<size_t>(pair.k)].q_W_I.conjugate();
      travel += q_I_W * Displacement(pair);
      up -= q_I_W * g_W_.normalized();
    }
    *travel_I = travel.normalized();
    *across_up_I = (up - up.dot(*travel_I) * *travel_I).normalized();
  }

  // The residual points of the scored pairs that find a plane within the gate at q_I_L, and
  // their score: each counts 1 - (distance / gate)^2, so that within the plateau a step leaves
  // (the points a step moves still lie within the gate) the nearer fit wins.
  Score operator()(const Eigen::Quaterniond& q_I_L) const {
    sensors::Calibration c = calibration_;
    c.q_I_L = q_I_L;
    std::vector<Score> per_pair(pairs_.size());
    ParallelFor(0, static_cast<int64_t>(pairs_.size()), num_threads_,
                [&](int64_t begin, int64_t end, int) {
                  for (int64_t i = begin; i < end; ++i) {
                    per_pair[static_cast<size_t>(i)] = Paired(pairs_[static_cast<size_t>(i)], c);
                  }
                });
    Score sum;
    for (const Score& part : per_pair) {
      sum.paired += part.paired;
      sum.value += part.value;
    }
    return sum;
  }

  bool empty() const { return pairs_.empty(); }

 private:
  Eigen::Vector3d Displacement(const ScoredPair& pair) const {
    const size_t k = static_cast<size_t>(pair.k);
    return keyframes_[k + 1].p_W_I - keyframes_[k].p_W_I;
  }

  Score Paired(const ScoredPair& pair, const sensors::Calibration& c) const {
    const size_t k = static_cast<size_t>(pair.k);
    const SelectedSweep& a = sweeps_[k];
    const SelectedSweep& b = sweeps_[k + 1];
    const lidar::PlaneMap map(
        SweepPointsInWorld(*pair.table_j, keyframes_[k + 1], b, b.map_points, g_W_, c),
        pairing_.plane_map);
    const Eigen::Matrix3Xd points_W =
        SweepPointsInWorld(*pair.table_k, keyframes_[k], a, a.residual_points, g_W_, c);
    const double gate_m = pairing_.max_point_to_plane_m;
    Score out;
    geometry::Plane plane;
    for (Eigen::Index i = 0; i < points_W.cols(); ++i) {
      const Eigen::Vector3d p = points_W.col(i);
      if (!map.FindPlane(p, &plane)) continue;
      const double d = std::abs(plane.SignedDistance(p)) / gate_m;
      if (d > 1.0) continue;
      ++out.paired;
      out.value += 1.0 - d * d;
    }
    return out;
  }

  const std::vector<SelectedSweep>& sweeps_;
  const std::vector<Keyframe>& keyframes_;
  const sensors::Calibration& calibration_;
  Eigen::Vector3d g_W_;
  PairingOptions pairing_;
  int num_threads_;
  std::vector<ScoredPair> pairs_;
};

// A candidate's place on the grid: steps about axes[0] and axes[1] from the given rotation.
using GridPoint = Eigen::Vector2i;

// Every candidate about `axis` through *best, within `steps` of the given rotation, the nearer
// to it first; *best moves to a higher score, or to an equal one nearer the given rotation.
template <typename Evaluate>
void SearchAbout(int axis, int steps, const Evaluate& evaluate, GridPoint* best, Score* best_score,
                 int* candidates) {
  const GridPoint centre = *best;
  for (int i = 0; i <= steps; ++i) {
    for (const int sign : {1, -1}) {
      GridPoint at = centre;
      at(axis) = sign * i;
      if ((i == 0 && sign < 0) || at == centre) continue;
      const Score score = evaluate(at);
      ++*candidates;
      const bool nearer = at.cwiseAbs().sum() < best->cwiseAbs().sum();
      if (score.value > best_score->value || (score.value == best_score->value && nearer)) {
        *best_score = score;
        *best = at;
      }
    }
  }
}

}  // namespace

StartingRotationSearch SearchStartingRotation(const sensors::ImuSamples& imu,
                                              const std::vector<SelectedSweep>& sweeps,
                                              const std::vector<Keyframe>& keyframes,
                                              const sensors::Calibration& calibration,
                                              const Eigen::Vector3d& g_W,
                                              const PairingOptions& pairing,
                                              const RotationSearchOptions& options) {
  StartingRotationSearch out;
  out.q_I_L_given = out.q_I_L_start = calibration.q_I_L;
  const PairingOptions coarse = CoarsePairing(pairing, kSearchCoarseFactor);
  const PairScore score(imu, sweeps, keyframes, calibration, g_W, coarse, options.scored_pairs,
                        options.num_threads);
  const double spacing_m = score.MedianSpacing();
  if (score.empty() || !(options.range_rad > 0.0) || !std::isfinite(spacing_m) ||
      !(spacing_m > 0.0)) {
    return out;
  }
  // Eq. P13: a step moves the scored points by one gate, so that every candidate's
  // neighbourhood in the cost is seen and none falls between two.
  const double step_rad =
      std::max(coarse.max_point_to_plane_m / spacing_m, options.range_rad / kMaxStepsPerSide);
  out.step_deg = step_rad * kRadToDeg;
  const int steps =
      static_cast<int>(std::min<double>(kMaxStepsPerSide, options.range_rad / step_rad));
  if (steps == 0) return out;
  out.searched = true;
  Eigen::Vector3d travel, up;
  score.Axes(&travel, &up);
  const Eigen::Vector3d axes[2] = {up, travel.cross(up)};  // yaw-like, then pitch-like
  const auto rotation = [&](const GridPoint& at) {
    return (geometry::Exp(Eigen::Vector3d(step_rad * (at.x() * axes[0] + at.y() * axes[1]))) *
            calibration.q_I_L)
        .normalized();
  };
  const auto evaluate = [&](const GridPoint& at) { return score(rotation(at)); };
  GridPoint best = GridPoint::Zero();
  Score best_score = score(calibration.q_I_L);
  out.paired_at_start = best_score.paired;
  out.candidates = 1;
  // About a through the given rotation, about b through the best, about a again if b moved it.
  SearchAbout(0, steps, evaluate, &best, &best_score, &out.candidates);
  SearchAbout(1, steps, evaluate, &best, &best_score, &out.candidates);
  if (best.y() != 0) SearchAbout(0, steps, evaluate, &best, &best_score, &out.candidates);
  out.paired_at_best = best_score.paired;
  if (best != GridPoint::Zero()) out.q_I_L_start = rotation(best);
  return out;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
