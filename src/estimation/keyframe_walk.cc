#include "estimation/keyframe_walk.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/geometry/so3.h"
#include "factors/point_group_storage.h"

namespace autocal {
namespace estimation {
namespace internal {

// The state of a keyframe paired for the first time; the misses restart with its map.
void KeyframeWalk::Start() {
  if (st_.partner_position.empty()) {
    st_.partner_position.assign(num_points_, -1);
    st_.plane_misses.assign(num_points_, 0);
    st_.tried_at.assign(num_points_ * P_, -1);
    st_.tries.assign(P_, {});
    st_.partner_walk = ctx_.settled ? ctx_.settled_count : P_;
  }
  walk_ = st_.partner_walk;
  // A point that found no plane in its last max_plane_misses lookups is not looked up again
  // until its own map is rebuilt.
  if (st_.misses_map_generation != s_.s.map->generation) {
    std::fill(st_.plane_misses.begin(), st_.plane_misses.end(), 0);
    st_.misses_map_generation = s_.s.map->generation;
  }
}

void KeyframeWalk::FindPartners() {
  partner_of_.assign(P_, -1);
  T_Lj_Lk_.assign(P_, geometry::Pose3d());
  change_.assign(P_, {});
  epoch_now_.assign(P_, -1);
  for (size_t q = 0; q < P_; ++q) {
    const auto it = ctx_.sweep_of_id.find(s_.s.id + partners_[q]);
    if (it == ctx_.sweep_of_id.end()) continue;
    partner_of_[q] = it->second;
    const SweepFrame& partner = ctx_.sweeps[static_cast<size_t>(it->second)];
    T_Lj_Lk_[q] = partner.T_Lj_W * s_.T_W_Lj;
    for (const PairingState::Try& t : st_.tries[q]) {
      if (t.map_generation != s_.s.map->generation ||
          t.partner_map_generation != partner.s.map->generation) {
        change_[q].emplace_back(std::numeric_limits<double>::infinity(), 0.0);
        continue;
      }
      const geometry::Pose3d d = t.T_Lj_Lk.Inverse() * T_Lj_Lk_[q];
      change_[q].emplace_back(d.p.norm(),
                              geometry::AngularDistance(d.q, Eigen::Quaterniond::Identity()));
    }
  }
}

// Nothing to do when the partners its points walk, positions [0, walk), are in the window as
// at the last pairing and every try a point refers to holds at the farthest residual point's
// range: each point then keeps its pair or stays without one (the walk would make no lookup
// and change nothing; the positions beyond the walk are never tried).
bool KeyframeWalk::Unchanged() {
  std::vector<bool> present(walk_);
  for (size_t q = 0; q < walk_; ++q) present[q] = partner_of_[q] >= 0;
  if (ctx_.window.skip_unchanged_keyframes && ctx_.window.reassociation_tolerance_m > 0.0 &&
      present == st_.partner_present) {
    bool all_hold = true;
    for (size_t q = 0; q < walk_ && all_hold; ++q) {
      for (size_t e = 0; e < change_[q].size(); ++e) {
        if (st_.tries_in_use[q][e] && !ctx_.TryHolds(change_[q][e], res_.max_range_m)) {
          all_hold = false;
          break;
        }
      }
    }
    if (all_hold) return true;
  }
  st_.partner_present = std::move(present);
  return false;
}

void KeyframeWalk::WalkPoints() {
  changed_.assign(P_, false);
  Keyframe& x = *s_.s.state;
  FiringPoses poses(x.q_W_I, x.p_W_I, x.v_W_I, ctx_.update.g_W);
  plane_side_.assign(P_, std::nullopt);
  repaired_.assign(num_points_, 0);
  terms_reserve_ =
      std::max(num_points_, static_cast<size_t>(std::max(ctx_.pairing.max_residuals_per_sweep, 0)));
  fresh_terms_.clear();
  fresh_terms_.reserve(terms_reserve_);
  for (size_t r = 0; r < num_points_; ++r) WalkPoint(r, &poses);
}

void KeyframeWalk::WalkPoint(size_t r, FiringPoses* poses) {
  const sensors::Calibration& c = *ctx_.update.calibration;
  const double offset_s = c.time_offset_lidar_imu_s;
  int current = st_.partner_position[r];
  if (current >= 0 && partner_of_[static_cast<size_t>(current)] < 0) {
    // Its partner was marginalized (the old pair's information is in the prior).
    changed_[static_cast<size_t>(current)] = true;
    st_.partner_position[r] = current = -1;
  }
  int* tried = &st_.tried_at[r * P_];
  const double range_m = res_.ranges_m[r];
  const size_t S = ctx_.settled_count;
  const int max_misses = ctx_.window.max_plane_misses;
  Eigen::Vector3d p_W;
  bool placed = false;
  for (size_t a = 0; a < walk_; ++a) {
    const size_t q = PartnerPosition(r, a, S, P_);
    const int j = partner_of_[q];
    if (j < 0) continue;
    if (tried[q] >= 0 && ctx_.TryHolds(change_[q][static_cast<size_t>(tried[q])], range_m)) {
      if (current == static_cast<int>(q)) break;  // its pair holds
      continue;                                   // still no plane there
    }
    const SweepFrame& other = ctx_.sweeps[static_cast<size_t>(j)];
    if (epoch_now_[q] < 0) {
      st_.tries[q].push_back({T_Lj_Lk_[q], s_.s.map->generation, other.s.map->generation});
      change_[q].emplace_back(0.0, 0.0);
      epoch_now_[q] = static_cast<int>(st_.tries[q].size()) - 1;
    }
    tried[q] = epoch_now_[q];
    if (!placed) {
      m_.p_L = res_.p_L.col(static_cast<Eigen::Index>(r));
      const double time_s = res_.time_s[r];
      const factors::PropagatedPose<double>& pose =
          poses->At(time_s, [&] { return s_.MotionAt(time_s, offset_s); });
      m_.motion = poses->motion();
      p_W = factors::PointInWorld(pose, c.q_I_L, c.p_I_L, m_.p_L);
      placed = true;
    }
    const Eigen::Vector3d p_Lj = other.T_Lj_W * p_W;
    uint8_t& misses = st_.plane_misses[r];
    bool plane = false;  // a lookup that is not made finds none
    // A point's own pair is always looked up again: only a lookup may end it.
    if (max_misses == 0 || misses < max_misses || current == static_cast<int>(q)) {
      ++lookups_;
      plane = other.s.map->planes->FindPlane(p_Lj, &m_.plane_L);
      misses = plane ? 0 : static_cast<uint8_t>(std::min(misses + 1, 255));
    }
    const bool found =
        plane && std::abs(m_.plane_L.SignedDistance(p_Lj)) <=
                     ctx_.pairing.max_point_to_plane_m + ctx_.gate_per_range * range_m;
    if (!found) {
      if (current == static_cast<int>(q)) {
        changed_[q] = true;
        st_.partner_position[r] = current = -1;
      }
      continue;
    }
    if (!plane_side_[q]) plane_side_[q].emplace(other.reference_motion, ctx_.update.g_W);
    m_.sigma_m = ctx_.pairing.point_sigma_m;
    m_.offset_linearization_s = offset_s;
    if (current >= 0) changed_[static_cast<size_t>(current)] = true;
    changed_[q] = true;
    st_.partner_position[r] = static_cast<int>(q);
    fresh_terms_.emplace_back(m_, ctx_.update.g_W);
    repaired_[r] = 1;
    // The partners after it in its list are tried again if this pair fails.
    for (size_t b = a + 1; b < P_; ++b) tried[PartnerPosition(r, b, S, P_)] = -1;
    break;
  }
}

// A changed group is edited in its own storage: the points whose pair held keep their terms
// where they are (the same pair, so the same terms), those that left it are dropped, and the
// points paired anew take theirs from the walk's terms, merged in so that the points stay in
// their order (MergeFreshPoints). A group of a partner new to the points takes storage from the
// pool.
void KeyframeWalk::EditChangedGroups() {
  members_.assign(P_, {});
  member_sides_.assign(P_, {});
  member_index_.assign(P_, {});
  held_.assign(P_, 0);
  written_.assign(P_, 0);
  for (SweepPointGroup& g : *s_.s.groups) {
    for (size_t q = 0; q < P_; ++q) {
      if (g.partner_id != s_.s.id + partners_[q] || !Rebuilt(q)) continue;
      EditGroup(q, &g);
    }
  }
}

void KeyframeWalk::EditGroup(size_t q, SweepPointGroup* g) {
  g->compressed.reset();  // it refers to the factor
  auto released = factors::ReleasePoints(std::move(g->factor));
  members_[q] = std::move(released.points);
  member_sides_[q] = std::move(released.plane_sides);
  member_index_[q] = std::move(g->point_index);
  written_[q] = members_[q].size();
  // Keep, in order, the points whose pair held.
  PointGroupPool::Storage& terms = members_[q];
  std::vector<int>& index = member_index_[q];
  for (size_t i = 0; i < index.size(); ++i) {
    const size_t r = static_cast<size_t>(index[i]);
    if (st_.partner_position[r] != static_cast<int>(q) || repaired_[r]) continue;
    terms[held_[q]] = terms[i];
    index[held_[q]] = index[i];
    ++held_[q];
  }
  terms.erase(terms.begin() + static_cast<std::ptrdiff_t>(held_[q]), terms.end());
  index.resize(held_[q]);
  // Drop the plane sides no held point refers to.
  std::vector<factors::PointToSweepPlaneFactor::Side>& sides = member_sides_[q];
  std::vector<uint32_t> renumbered(sides.size(), 0);
  for (const auto& t : terms) renumbered[t.plane_side()] = 1;
  uint32_t used = 0;
  for (size_t e = 0; e < sides.size(); ++e) {
    if (!renumbered[e]) continue;
    sides[used] = sides[e];
    renumbered[e] = used++;
  }
  if (used < sides.size()) {
    sides.erase(sides.begin() + used, sides.end());
    for (auto& t : terms) t.set_plane_side(renumbered[t.plane_side()]);
  }
}

void KeyframeWalk::MergeFreshPoints() {
  // The points paired anew per partner position (residual point, place in fresh_terms), in
  // their order, and the count of the pairs that held, which the groups must hold.
  std::vector<std::vector<std::pair<int, size_t>>> fresh_of(P_);
  std::vector<size_t> expected_held(P_, 0);
  size_t fresh = 0;
  for (size_t r = 0; r < num_points_; ++r) {
    const int position_r = st_.partner_position[r];
    if (position_r < 0) continue;
    const size_t q = static_cast<size_t>(position_r);
    if (repaired_[r]) {
      fresh_of[q].emplace_back(static_cast<int>(r), fresh++);
    } else if (changed_[q]) {
      ++expected_held[q];
    }
  }
  for (size_t q = 0; q < P_; ++q) {
    if (!changed_[q]) continue;
    if (held_[q] != expected_held[q]) {
      // A pair that held is in the group of its partner, which every change rebuilds.
      throw Error("SlidingWindowEstimator: keyframe " + std::to_string(s_.s.id) + " kept " +
                  std::to_string(expected_held[q]) + " pairs with keyframe " +
                  std::to_string(s_.s.id + partners_[q]) + " but its point group holds " +
                  std::to_string(held_[q]));
    }
    const std::vector<std::pair<int, size_t>>& anew = fresh_of[q];
    if (anew.empty()) continue;
    PointGroupPool::Storage& terms = members_[q];
    std::vector<int>& index = member_index_[q];
    const size_t n = held_[q] + anew.size();
    if (terms.capacity() < n) {
      // Storage that holds them from the pool, the group's own kept for another.
      PointGroupPool::Storage grown = ctx_.pool->Take(n, terms_reserve_);
      grown.insert(grown.end(), terms.begin(), terms.end());
      ctx_.pool->Keep(std::exchange(terms, std::move(grown)), written_[q]);
      written_[q] = 0;
    }
    // The new points' plane side, this walk's with partner q.
    std::vector<factors::PointToSweepPlaneFactor::Side>& sides = member_sides_[q];
    sides.push_back(*plane_side_[q]);
    for (const auto& [r, f] : anew) {
      fresh_terms_[f].set_plane_side(static_cast<uint32_t>(sides.size() - 1));
    }
    index.reserve(n);
    // Grow by the new points, then merge from the back: the held points move only to later
    // places, none before it was read.
    for (const auto& [r, f] : anew) {
      terms.push_back(fresh_terms_[f]);
      index.push_back(r);
    }
    size_t i = held_[q];     // held points [0, i) not yet placed
    size_t a = anew.size();  // new points [0, a) not yet placed
    for (size_t out = n; a > 0;) {
      --out;
      if (i > 0 && index[i - 1] > anew[a - 1].first) {
        --i;
        terms[out] = terms[i];
        index[out] = index[i];
      } else {
        --a;
        terms[out] = fresh_terms_[anew[a].second];
        index[out] = anew[a].first;
      }
    }
  }
}

void KeyframeWalk::FormGroups() {
  sensors::Calibration& c = *ctx_.update.calibration;
  Keyframe& x = *s_.s.state;
  for (size_t q = 0; q < P_; ++q) {
    if (!Rebuilt(q)) continue;
    const int partner_id = s_.s.id + partners_[q];
    const int j = partner_of_[q];
    if (j < 0 && !st_.tries[q].empty()) {  // it left the window for good
      st_.tries[q].clear();
      for (size_t r = 0; r < num_points_; ++r) st_.tried_at[r * P_ + q] = -1;
    }
    if (j < 0 || members_[q].empty()) {
      ctx_.pool->Keep(std::move(members_[q]), written_[q]);
      continue;
    }
    Keyframe& y = *ctx_.sweeps[static_cast<size_t>(j)].s.state;
    SweepPointGroup group;
    group.partner_id = partner_id;
    group.factor = std::make_unique<factors::PointToSweepPlaneGroupFactor>(
        std::move(members_[q]), std::move(member_sides_[q]), ctx_.point_loss);
    group.point_index = std::move(member_index_[q]);
    if (group.factor->num_residuals() > CompressedPointGroup::kRows) {
      group.compressed = std::make_unique<CompressedPointGroup>(group.factor.get());
    }
    group.parameters = {x.q_W_I.coeffs().data(), x.p_W_I.data(), x.v_W_I.data(),
                        y.q_W_I.coeffs().data(), y.p_W_I.data(), y.v_W_I.data(),
                        c.q_I_L.coeffs().data(), c.p_I_L.data(), &c.time_offset_lidar_imu_s};
    s_.s.groups->push_back(std::move(group));
  }
}

// The tries some point refers to (for Unchanged at the next update).
void KeyframeWalk::MarkTriesInUse() {
  st_.tries_in_use.resize(walk_);
  for (size_t q = 0; q < walk_; ++q) st_.tries_in_use[q].assign(st_.tries[q].size(), 0);
  for (size_t r = 0; r < num_points_; ++r) {
    for (size_t q = 0; q < walk_; ++q) {
      const int t = st_.tried_at[r * P_ + q];
      if (t >= 0) st_.tries_in_use[q][static_cast<size_t>(t)] = 1;
    }
  }
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
