#pragma once

// One keyframe's walk of the sliding window's pairing (SweepPairing, sweep_pairing.h): the
// per-update view of the window's sweeps, and the walk that makes a keyframe's missing and
// stale tries and rebuilds its changed point groups.

#include <cstdint>
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include "autocal/common/time.h"
#include "estimation/firing_poses.h"
#include "estimation/sweep_pairing.h"

namespace autocal {
namespace estimation {
namespace internal {

// A window sweep at this update's estimate: its IMU motion table from its keyframe and its
// LiDAR pose at the reference instant.
struct SweepFrame {
  PairingSweep s;
  std::optional<ImuMotionTable> table;
  factors::PointMotion reference_motion;
  geometry::Pose3d T_W_Lj;
  geometry::Pose3d T_Lj_W;

  factors::PointMotion MotionAt(double point_time_s, double offset_s) const {
    return table->At(s.sweep->t_ns + SecondsToNs(point_time_s + offset_s));
  }
};

// What the walks of one update share.
struct WalkContext {
  const PairingOptions& pairing;
  const WindowPairingOptions& window;
  const factors::LossOptions& point_loss;
  const std::vector<SweepFrame>& sweeps;
  std::map<int, int> sweep_of_id;  // window keyframe id -> index in sweeps
  const PairingUpdate& update;
  double gate_per_range = 0.0;  // the gate's widening per metre of range
  bool settled = false;         // the extrinsic rotation has settled
  size_t settled_count = 0;     // S
  PointGroupPool* pool = nullptr;

  // Whether a try still holds for a point at range_m: its pose change (|dp|, angle) moves the
  // point by at most the tolerance (Eq. W1).
  bool TryHolds(const std::pair<double, double>& d, double range_m) const {
    const double tolerance_m = window.reassociation_tolerance_m;
    return tolerance_m > 0.0 && d.first + d.second * range_m <= tolerance_m;
  }
};

// One keyframe's pairing at one update (docs/sliding_window.md, "Partner walk" and "Reuse between
// updates"): residual point r tries the partner positions in the order of PartnerPosition and is
// paired with the first sweep k + o in the window that holds a plane within the gate of T_Lj_W p_W,
// p_W the point in W at the current estimate. The plane is kept in L_j ("The point group factor"),
// so in the solve it moves with keyframe j and the extrinsic. What a try found (a plane, or none)
// is kept with the relative pose T_Lj_Lk it was made at and holds while that pose moved by at most
// reassociation_tolerance_m at the point's range (Eq. W1); only tries that are missing or stale are
// made again, and only the groups that changed are rebuilt.
class KeyframeWalk {
 public:
  KeyframeWalk(const WalkContext& ctx, int k, PointGroupPool::Storage* fresh_terms)
      : ctx_(ctx),
        k_(k),
        s_(ctx.sweeps[static_cast<size_t>(k)]),
        st_(*s_.s.pairing),
        res_(*s_.s.residuals),
        partners_(ctx.pairing.partner_offsets),
        P_(partners_.size()),
        num_points_(res_.size()),
        fresh_terms_(*fresh_terms) {}

  // Returns the plane lookups made.
  int Run() {
    Start();
    FindPartners();
    if (Unchanged()) return 0;
    WalkPoints();
    EditChangedGroups();
    for (size_t q = 0; q < P_; ++q) {
      if (Rebuilt(q)) ctx_.pool->RetireGroupsOf(s_.s.groups, s_.s.id + partners_[q]);
    }
    MergeFreshPoints();
    FormGroups();
    MarkTriesInUse();
    return lookups_;
  }

 private:
  void Start();
  void FindPartners();
  bool Unchanged();
  void WalkPoints();
  void WalkPoint(size_t r, FiringPoses* poses);
  void EditChangedGroups();
  void EditGroup(size_t q, SweepPointGroup* g);
  void MergeFreshPoints();
  void FormGroups();
  void MarkTriesInUse();
  bool Rebuilt(size_t q) const { return changed_[q] || partner_of_[q] < 0; }

  const WalkContext& ctx_;
  const int k_;
  const SweepFrame& s_;
  PairingState& st_;
  const ResidualPoints& res_;
  const std::vector<int>& partners_;
  const size_t P_;
  const size_t num_points_;
  size_t walk_ = 0;
  int lookups_ = 0;
  // Per partner position q: its window position (-1: not in the window), the relative pose
  // now, and per earlier try the change to now, (|dp|, angle) of Eq. W1 (infinite when either
  // sweep's map was rebuilt since: the deskew moved).
  std::vector<int> partner_of_;
  std::vector<geometry::Pose3d> T_Lj_Lk_;
  std::vector<std::vector<std::pair<double, double>>> change_;
  std::vector<int> epoch_now_;  // index of this update's try in tries[q], once made
  std::vector<bool> changed_;   // partner positions whose group changed
  // Every field of m a pair uses is set for its point (p_L and motion when placed, the plane's
  // when paired), so one measurement serves the whole walk.
  factors::PointToSweepPlaneMeasurement m_;
  // The plane side of the walk's pairs with each partner position: its sweep's reference
  // motion, the same for all of them (Terms hold only the point's side).
  std::vector<std::optional<factors::PointToSweepPlaneFactor::Side>> plane_side_;
  std::vector<uint8_t> repaired_;  // paired anew by this walk
  // The most terms a group of this keyframe, or a walk, forms (every keyframe's count, so that
  // storage passes between keyframes without growing).
  size_t terms_reserve_ = 0;
  // The terms of the points the walk pairs anew, in their order, until the groups take them.
  PointGroupPool::Storage& fresh_terms_;
  // The changed groups being rebuilt, per partner position.
  std::vector<PointGroupPool::Storage> members_;
  std::vector<std::vector<factors::PointToSweepPlaneFactor::Side>> member_sides_;
  std::vector<std::vector<int>> member_index_;
  std::vector<size_t> held_;     // points whose pair held, per partner position
  std::vector<size_t> written_;  // how far a released group's storage was written
};

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
