// The window problem of the sliding window (docs/sliding_window.md, "One update" steps 3-5):
// associating the points, building it, solving it, marginalizing its oldest keyframe and its
// calibration covariance.
#include "autocal/estimation/sliding_window.h"

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
#include "autocal/factors/imu_factor.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "factors/point_group_storage.h"
#include "autocal/geometry/se3.h"
#include "autocal/geometry/so3.h"
#include "estimation/firing_poses.h"
#include "estimation/sliding_window_internal.h"
#include "estimation/window_solver.h"

namespace autocal {
namespace estimation {

using internal::AttachedFactor;
using internal::StateBlocks;

namespace {

constexpr double kDegToRad = M_PI / 180.0;

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
  internal::FiringPoses poses(kf.q_W_I, kf.p_W_I, kf.v_W_I, g_W);
  for (int i : indices) {
    const double time_s = sweep.cloud.time_s(i);
    const factors::PropagatedPose<double>& pose = poses.At(time_s, [&] {
      return table.At(sweep.t_ns + SecondsToNs(time_s + c.time_offset_lidar_imu_s));
    });
    points_W.col(column++) =
        factors::PointInWorld(pose, c.q_I_L, c.p_I_L, sweep.cloud.points.col(i));
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

// A keyframe's LiDAR pose T_W_I T_I_L, its IMU pose moved by dt_s at its velocity and at the
// angular rate w_I (Eq. SW12).
geometry::Pose3d LidarPose(const SlidingWindowState& x, const sensors::Calibration& c,
                           const Eigen::Vector3d& w_I, double dt_s) {
  const Eigen::Quaterniond q_W_I = x.q_W_I * geometry::Exp(Eigen::Vector3d(w_I * dt_s));
  return geometry::Pose3d(q_W_I * c.q_I_L, x.p_W_I + x.v_W_I * dt_s + q_W_I * c.p_I_L);
}

}  // namespace

// Step 3 (docs/sliding_window.md, "Association" and "Reuse between updates"). Every window
// sweep j gets its IMU motion table from keyframe j at the current estimate and its LiDAR pose
// at the reference instant (point time 0), T_W_Lj = T_W_I(t_j) T_I_L. Its plane map holds the
// map points deskewed into L_j at that instant; it is rebuilt when the deskew moved a point by
// more than map_rebuild_tolerance_m (Eq. SW4). A residual point due for pairing (below) is
// placed in W at the current estimate, p_W, and tries the sweeps j = k + o for the offsets o
// of partner_keyframe_offsets (starting at a different one for consecutive points; only the
// first settled_partner_count once the extrinsic has settled, Eq. SW15): the first
// that holds a plane within max_point_to_plane_m of T_Lj_W p_W is its partner. The plane is kept in
// L_j (Eq. SW3), so in the solve it moves with keyframe j's q, p, v and with q_I_L, p_I_L and the
// time offset. The points of keyframe k on planes of sweep j form one group factor (Eq. P9).
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
      ++kf.map_generation;
      kf.map_max_range_m = 0.0;
      for (int i : kf.map_points) {
        kf.map_max_range_m = std::max(kf.map_max_range_m, kf.sweep->cloud.points.col(i).norm());
      }
    }
  });

  // Pairing (docs/sliding_window.md, "Association" and "Reuse between updates"). Residual
  // point r of keyframe k tries the first S = settled_partner_count partner offsets in the
  // order o_{(r + a) mod S}, a = 0 .. S - 1, then (unless the extrinsic had settled when k was
  // first paired, Eq. SW15) the other P - S likewise, and is paired with the first sweep
  // k + o in the window that holds a plane for it. What a try found (a plane, or none) is
  // kept with the relative pose T_Lj_Lk it was made at, and holds while that pose has moved
  // by at most reassociation_tolerance_m at the point's range (Eq. SW4); only tries that are
  // missing (a sweep that entered the window, a partner that left it) or stale are made
  // again. The points of k on planes of sweep j form one group factor (Eq. P9); only the
  // groups that changed are rebuilt.
  std::map<int, int> sweep_of_id;
  for (int k = 0; k < num_sweeps; ++k) sweep_of_id[sweeps[static_cast<size_t>(k)].kf->id] = k;
  const std::vector<int>& partners = options_.partner_keyframe_offsets;
  const int num_partners = static_cast<int>(partners.size());
  const double tolerance_m = options_.reassociation_tolerance_m;
  // Whether a try still holds for a point at range_m: its pose change (|dp|, angle) moves the
  // point by at most the tolerance (Eq. SW4).
  const auto try_holds = [tolerance_m](const std::pair<double, double>& d, double range_m) {
    return tolerance_m > 0.0 && d.first + d.second * range_m <= tolerance_m;
  };
  // Eq. SW14: the gate widens while the extrinsic rotation moves.
  const double recent_rotation_rad =
      recent_q_I_L_.empty() ? 0.0 : geometry::AngularDistance(recent_q_I_L_.front(), c.q_I_L);
  const double gate_per_range =
      options_.gate_extrinsic_factor *
      std::max(0.0, recent_rotation_rad - options_.gate_extrinsic_free_deg * kDegToRad);
  // Eq. SW15: the points try partner positions [0, S) first, the others after them; the points
  // of a keyframe first paired once the extrinsic rotation has settled only [0, S).
  const size_t S = std::min(static_cast<size_t>(options_.settled_partner_count),
                            static_cast<size_t>(num_partners));
  timing_.extrinsic_settled = static_cast<int>(recent_q_I_L_.size()) >= options_.window_size &&
                              recent_rotation_rad <= options_.settled_extrinsic_deg * kDegToRad;
  std::vector<int> lookups(static_cast<size_t>(num_sweeps), 0);
  terms_pool_->SetChunks(std::max(options_.num_threads, 1));  // at least ParallelFor's chunks
  ParallelFor(0, num_sweeps, options_.num_threads, [&](int64_t begin, int64_t end, int chunk) {
    // The terms of the points a walk pairs anew, in their order, until the groups take them.
    TermsPool::Storage& fresh_terms = terms_pool_->Fresh(chunk);
    for (int64_t kk = begin; kk < end; ++kk) {
      const int k = static_cast<int>(kk);
      const LidarKeyframe& s = sweeps[static_cast<size_t>(k)];
      WindowKeyframe& kf = *s.kf;
      const size_t num_points = kf.residual_points.size();
      const size_t P = static_cast<size_t>(num_partners);
      if (kf.partner_position.empty()) {
        kf.partner_position.assign(num_points, -1);
        kf.plane_misses.assign(num_points, 0);
        kf.tried_at.assign(num_points * P, -1);
        kf.tries.assign(P, {});
        kf.partner_walk = timing_.extrinsic_settled ? S : P;
      }
      const size_t walk = kf.partner_walk;
      // A point that found no plane in its last max_plane_misses lookups is not looked up
      // again until its own map is rebuilt.
      const int max_misses = options_.max_plane_misses;
      if (kf.misses_map_generation != kf.map_generation) {
        std::fill(kf.plane_misses.begin(), kf.plane_misses.end(), 0);
        kf.misses_map_generation = kf.map_generation;
      }
      // Per partner position q: its window position (-1: not in the window), the relative
      // pose now, and per earlier try the change to now, (|dp|, angle) of Eq. SW4 (infinite
      // when either sweep's map was rebuilt since: the deskew moved).
      std::vector<int> partner_of(P, -1);
      std::vector<geometry::Pose3d> T_Lj_Lk(P);
      std::vector<std::vector<std::pair<double, double>>> change(P);
      std::vector<int> epoch_now(P, -1);  // index of this update's try in tries[q], once made
      for (size_t q = 0; q < P; ++q) {
        const auto it = sweep_of_id.find(kf.id + partners[q]);
        if (it == sweep_of_id.end()) continue;
        partner_of[q] = it->second;
        T_Lj_Lk[q] = sweeps[static_cast<size_t>(it->second)].T_Lj_W * s.T_W_Lj;
        const WindowKeyframe& partner = *sweeps[static_cast<size_t>(it->second)].kf;
        for (const WindowKeyframe::Try& t : kf.tries[q]) {
          if (t.map_generation != kf.map_generation ||
              t.partner_map_generation != partner.map_generation) {
            change[q].emplace_back(std::numeric_limits<double>::infinity(), 0.0);
            continue;
          }
          const geometry::Pose3d d = t.T_Lj_Lk.Inverse() * T_Lj_Lk[q];
          change[q].emplace_back(d.p.norm(),
                                 geometry::AngularDistance(d.q, Eigen::Quaterniond::Identity()));
        }
      }
      // Nothing to do when the partners its points walk, positions [0, walk), are in the
      // window as at the last pairing and every try a point refers to holds at the farthest
      // residual point's range: each point then keeps its pair or stays without one (the walk
      // below would make no lookup and change nothing; the positions beyond the walk are never
      // tried).
      std::vector<bool> present(walk);
      for (size_t q = 0; q < walk; ++q) present[q] = partner_of[q] >= 0;
      if (options_.skip_unchanged_keyframes && tolerance_m > 0.0 && present == kf.partner_present) {
        bool all_hold = true;
        for (size_t q = 0; q < walk && all_hold; ++q) {
          for (size_t e = 0; e < change[q].size(); ++e) {
            if (kf.tries_in_use[q][e] && !try_holds(change[q][e], kf.residual_max_range_m)) {
              all_hold = false;
              break;
            }
          }
        }
        if (all_hold) continue;
      }
      kf.partner_present = std::move(present);
      std::vector<bool> changed(P, false);
      SlidingWindowState& x = kf.state;
      internal::FiringPoses poses(x.q_W_I, x.p_W_I, x.v_W_I, g_W_);
      // The a-th partner position point r tries (Eq. SW15).
      const auto position = [S, P](size_t r, size_t a) {
        return a < S ? (r + a) % S : S + (r + a - S) % (P - S);
      };
      // Every field of m a pair uses is set for its point below (p_L and motion when placed,
      // the plane's when paired), so one measurement serves the whole walk.
      factors::PointToSweepPlaneMeasurement m;
      // The plane side of the walk's pairs with each partner position: its sweep's reference
      // motion, the same for all of them (Terms hold only the point's side).
      std::vector<std::optional<factors::PointToSweepPlaneFactor::Side>> plane_side(P);
      std::vector<uint8_t> repaired(num_points, 0);  // paired anew by this walk
      // The most terms a group of this keyframe, or a walk, forms (every keyframe's count, so
      // that storage passes between keyframes without growing).
      const size_t terms_reserve = std::max(
          num_points, static_cast<size_t>(std::max(options_.max_residuals_per_sweep, 0)));
      fresh_terms.clear();
      fresh_terms.reserve(terms_reserve);
      for (size_t r = 0; r < num_points; ++r) {
        int current = kf.partner_position[r];
        if (current >= 0 && partner_of[static_cast<size_t>(current)] < 0) {
          // Its partner was marginalized (the old pair's information is in the prior).
          changed[static_cast<size_t>(current)] = true;
          kf.partner_position[r] = current = -1;
        }
        int* tried = &kf.tried_at[r * P];
        const double range_m = kf.residual_ranges_m[r];
        Eigen::Vector3d p_W;
        bool placed = false;
        for (size_t a = 0; a < walk; ++a) {
          const size_t q = position(r, a);
          const int j = partner_of[q];
          if (j < 0) continue;
          if (tried[q] >= 0 && try_holds(change[q][static_cast<size_t>(tried[q])], range_m)) {
            if (current == static_cast<int>(q)) break;  // its pair holds
            continue;                                   // still no plane there
          }
          const LidarKeyframe& other = sweeps[static_cast<size_t>(j)];
          if (epoch_now[q] < 0) {
            kf.tries[q].push_back({T_Lj_Lk[q], kf.map_generation, other.kf->map_generation});
            change[q].emplace_back(0.0, 0.0);
            epoch_now[q] = static_cast<int>(kf.tries[q].size()) - 1;
          }
          tried[q] = epoch_now[q];
          if (!placed) {
            m.p_L = kf.residual_p_L.col(static_cast<Eigen::Index>(r));
            const double time_s = kf.residual_time_s[r];
            const factors::PropagatedPose<double>& pose =
                poses.At(time_s, [&] { return motion_at(s, time_s); });
            m.motion = poses.motion();
            p_W = factors::PointInWorld(pose, c.q_I_L, c.p_I_L, m.p_L);
            placed = true;
          }
          const Eigen::Vector3d p_Lj = other.T_Lj_W * p_W;
          uint8_t& misses = kf.plane_misses[r];
          bool plane = false;  // a lookup that is not made finds none
          // A point's own pair is always looked up again: only a lookup may end it.
          if (max_misses == 0 || misses < max_misses || current == static_cast<int>(q)) {
            ++lookups[static_cast<size_t>(k)];
            plane = other.kf->plane_map->FindPlane(p_Lj, &m.plane_L);
            misses = plane ? 0 : static_cast<uint8_t>(std::min(misses + 1, 255));
          }
          const bool found = plane &&
                             std::abs(m.plane_L.SignedDistance(p_Lj)) <=
                                 options_.max_point_to_plane_m + gate_per_range * range_m;
          if (!found) {
            if (current == static_cast<int>(q)) {
              changed[q] = true;
              kf.partner_position[r] = current = -1;
            }
            continue;
          }
          if (!plane_side[q]) plane_side[q].emplace(other.reference_motion, g_W_);
          m.sigma_m = options_.point_sigma_m;
          m.offset_linearization_s = offset_lin;
          if (current >= 0) changed[static_cast<size_t>(current)] = true;
          changed[q] = true;
          kf.partner_position[r] = static_cast<int>(q);
          fresh_terms.emplace_back(m, g_W_);
          repaired[r] = 1;
          // The partners after it in its list are tried again if this pair fails.
          for (size_t b = a + 1; b < P; ++b) tried[position(r, b)] = -1;
          break;
        }
      }
      // Rebuild the groups of the partners whose points changed. A changed group is edited in
      // its own storage: the points whose pair held keep their terms where they are (the same
      // pair, so the same terms), those that left it are dropped, and the points paired anew
      // take theirs from fresh_terms, merged in so that the points stay in their order. A
      // group of a partner new to the points takes storage from the pool.
      const auto rebuilt = [&](size_t q) { return changed[q] || partner_of[q] < 0; };
      std::vector<internal::SweepPointGroup>& groups = kf.point_groups;
      std::vector<TermsPool::Storage> members(P);
      std::vector<std::vector<factors::PointToSweepPlaneFactor::Side>> member_sides(P);
      std::vector<std::vector<int>> member_index(P);
      std::vector<size_t> held(P, 0);  // points whose pair held, per partner position
      std::vector<size_t> written(P, 0);  // how far a released group's storage was written
      for (internal::SweepPointGroup& g : groups) {
        for (size_t q = 0; q < P; ++q) {
          if (g.partner_id != kf.id + partners[q] || !rebuilt(q)) continue;
          g.compressed.reset();  // it refers to the factor
          auto released = factors::ReleasePoints(std::move(g.factor));
          members[q] = std::move(released.points);
          member_sides[q] = std::move(released.plane_sides);
          member_index[q] = std::move(g.point_index);
          written[q] = members[q].size();
          // Keep, in order, the points whose pair held.
          TermsPool::Storage& terms = members[q];
          std::vector<int>& index = member_index[q];
          for (size_t i = 0; i < index.size(); ++i) {
            const size_t r = static_cast<size_t>(index[i]);
            if (kf.partner_position[r] != static_cast<int>(q) || repaired[r]) continue;
            terms[held[q]] = terms[i];
            index[held[q]] = index[i];
            ++held[q];
          }
          terms.erase(terms.begin() + static_cast<std::ptrdiff_t>(held[q]), terms.end());
          index.resize(held[q]);
          // Drop the plane sides no held point refers to.
          std::vector<factors::PointToSweepPlaneFactor::Side>& sides = member_sides[q];
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
      }
      // The released groups leave the window's list at once (none is left without its factor).
      for (size_t q = 0; q < P; ++q) {
        if (rebuilt(q)) terms_pool_->RetireGroupsOf(&groups, kf.id + partners[q]);
      }
      // The points paired anew per partner position (residual point, place in fresh_terms),
      // in their order, and the count of the pairs that held, which the groups must hold.
      std::vector<std::vector<std::pair<int, size_t>>> fresh_of(P);
      std::vector<size_t> expected_held(P, 0);
      size_t fresh = 0;
      for (size_t r = 0; r < num_points; ++r) {
        const int position_r = kf.partner_position[r];
        if (position_r < 0) continue;
        const size_t q = static_cast<size_t>(position_r);
        if (repaired[r]) {
          fresh_of[q].emplace_back(static_cast<int>(r), fresh++);
        } else if (changed[q]) {
          ++expected_held[q];
        }
      }
      for (size_t q = 0; q < P; ++q) {
        if (!changed[q]) continue;
        if (held[q] != expected_held[q]) {
          // A pair that held is in the group of its partner, which every change rebuilds.
          throw Error("SlidingWindowEstimator: keyframe " + std::to_string(kf.id) + " kept " +
                      std::to_string(expected_held[q]) + " pairs with keyframe " +
                      std::to_string(kf.id + partners[q]) + " but its point group holds " +
                      std::to_string(held[q]));
        }
        const std::vector<std::pair<int, size_t>>& anew = fresh_of[q];
        if (anew.empty()) continue;
        TermsPool::Storage& terms = members[q];
        std::vector<int>& index = member_index[q];
        const size_t n = held[q] + anew.size();
        if (terms.capacity() < n) {
          // Storage that holds them from the pool, the group's own kept for another.
          TermsPool::Storage grown = terms_pool_->Take(n, terms_reserve);
          grown.insert(grown.end(), terms.begin(), terms.end());
          terms_pool_->Keep(std::exchange(terms, std::move(grown)), written[q]);
          written[q] = 0;
        }
        // The new points' plane side, this walk's with partner q.
        std::vector<factors::PointToSweepPlaneFactor::Side>& sides = member_sides[q];
        sides.push_back(*plane_side[q]);
        for (const auto& [r, f] : anew) {
          fresh_terms[f].set_plane_side(static_cast<uint32_t>(sides.size() - 1));
        }
        index.reserve(n);
        // Grow by the new points, then merge from the back: the held points move only to
        // later places, none before it was read.
        for (const auto& [r, f] : anew) {
          terms.push_back(fresh_terms[f]);
          index.push_back(r);
        }
        size_t i = held[q];     // held points [0, i) not yet placed
        size_t a = anew.size(); // new points [0, a) not yet placed
        for (size_t out = n; a > 0;) {
          --out;
          if (i > 0 && index[i - 1] > anew[a - 1].first) {
            --i;
            terms[out] = terms[i];
            index[out] = index[i];
          } else {
            --a;
            terms[out] = fresh_terms[anew[a].second];
            index[out] = anew[a].first;
          }
        }
      }
      for (size_t q = 0; q < P; ++q) {
        if (!rebuilt(q)) continue;
        const int partner_id = kf.id + partners[q];
        const int j = partner_of[q];
        if (j < 0 && !kf.tries[q].empty()) {  // it left the window for good
          kf.tries[q].clear();
          for (size_t r = 0; r < num_points; ++r) kf.tried_at[r * P + q] = -1;
        }
        if (j < 0 || members[q].empty()) {
          terms_pool_->Keep(std::move(members[q]), written[q]);
          continue;
        }
        SlidingWindowState& y = sweeps[static_cast<size_t>(j)].kf->state;
        internal::SweepPointGroup group;
        group.partner_id = partner_id;
        group.factor = std::make_unique<factors::PointToSweepPlaneGroupFactor>(
            std::move(members[q]), std::move(member_sides[q]), options_.loss.lidar);
        group.point_index = std::move(member_index[q]);
        if (group.factor->num_residuals() > internal::CompressedPointGroup::kRows) {
          group.compressed = std::make_unique<internal::CompressedPointGroup>(group.factor.get());
        }
        group.parameters = {x.q_W_I.coeffs().data(), x.p_W_I.data(), x.v_W_I.data(),
                            y.q_W_I.coeffs().data(), y.p_W_I.data(), y.v_W_I.data(),
                            calibration_.q_I_L.coeffs().data(), calibration_.p_I_L.data(),
                            &calibration_.time_offset_lidar_imu_s};
        groups.push_back(std::move(group));
      }
      // The tries some point refers to (the skip above).
      kf.tries_in_use.resize(walk);
      for (size_t q = 0; q < walk; ++q) kf.tries_in_use[q].assign(kf.tries[q].size(), 0);
      for (size_t r = 0; r < num_points; ++r) {
        for (size_t q = 0; q < walk; ++q) {
          const int t = kf.tried_at[r * P + q];
          if (t >= 0) kf.tries_in_use[q][static_cast<size_t>(t)] = 1;
        }
      }
    }
  });
  for (int n : lookups) timing_.plane_lookups += n;
}

std::unique_ptr<SlidingWindowEstimator::ProblemBuild> SlidingWindowEstimator::BuildProblem(
    const std::vector<double>* group_motions) {
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

  const bool linearize = options_.point_linearizations_per_update > 0;
  const auto relinearized = [&build, linearize](ceres::ResidualBlockId id, bool always) {
    if (always || !linearize) build->relinearized.push_back(id);
  };
  const auto add = [&problem, &build, linearize, &relinearized](const AttachedFactor& f) {
    if (linearize && f.linearized_per_pass != nullptr) {
      // Its loss's weight is held for the pass (Eq. SW13).
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
  // The point groups carry the LiDAR loss themselves (Eq. P9); in a later pass each keeps its
  // linearization while its sweeps stay within relinearization_tolerance_m of it (Eq. SW12).
  std::map<int, const WindowKeyframe*> keyframe_of_id;
  for (const auto& kf : window_) keyframe_of_id[kf->id] = kf.get();
  size_t index = 0;
  for (const auto& kf : window_) {
    for (internal::SweepPointGroup& g : kf->point_groups) {
      if (!linearize) {
        relinearized(problem.AddResidualBlock(g.solver_cost(), nullptr, g.parameters), false);
        continue;
      }
      const bool moved = group_motions == nullptr ||
                         !((*group_motions)[index++] <= options_.relinearization_tolerance_m);
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
  return build;
}

double SlidingWindowEstimator::SquaredPointDistances(bool oldest_only) const {
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
  return sum * options_.point_sigma_m * options_.point_sigma_m;
}

double SlidingWindowEstimator::last_point_rms_m() const {
  if (!last_point_rms_m_) {
    last_point_rms_m_ =
        last_associated_points_ == 0
            ? 0.0
            : std::sqrt((dropped_point_squared_m2_ + SquaredPointDistances(false)) /
                        static_cast<double>(last_associated_points_));
  }
  return *last_point_rms_m_;
}

// Eq. SW12: how far each point group's points moved since the group was linearized: its two
// sweeps' relative motion, bounded as in Eq. SW4 at the range of the keyframe's farthest
// residual point, plus the change of each sweep's deskew (its velocity's change times its
// duration). A sweep's LiDAR pose is T_W_I T_I_L at its keyframe, moved by the change of the
// time offset since at the keyframe's velocity and at its mean angular rate over the interval
// from the previous keyframe (to the next, for the oldest).
std::vector<double> SlidingWindowEstimator::PointGroupMotions() const {
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
      // The deskew within each sweep moves a point by at most its velocity's change times the
      // sweep's duration.
      const double deskew_m = (kf.state.v_W_I - l.v_W_Ik).norm() * kf.sweep_duration_s +
                              (partner.state.v_W_I - l.v_W_Ij).norm() * partner.sweep_duration_s;
      motions.push_back(MaxPointMotion(l.T_W_Lj.Inverse() * l.T_W_Lk, T_W_Lj.Inverse() * T_W_Lk,
                                       kf.residual_max_range_m) +
                        deskew_m);
    }
  }
  return motions;
}

// With the points linearized per pass (Eq. SW7) the solve runs up to
// point_linearizations_per_update passes, each on the point groups relinearized where the
// previous pass ended, and stops early once no group's sweeps moved by more than
// relinearization_tolerance_m since its linearization (Eq. SW12).
void SlidingWindowEstimator::Solve(std::unique_ptr<ProblemBuild>* build) {
  // The window's own Levenberg-Marquardt (Eq. SW11): the rows fixed for the pass enter by
  // their normal equations, formed once; an iteration evaluates the IMU factors and the rows
  // with a loss and factors the dense system. It runs on one thread (docs/sliding_window.md,
  // "Solver: threads").
  internal::WindowSolverOptions solver_options;
  solver_options.max_iterations = options_.solver_iterations;
  solver_options.function_tolerance = options_.solver_function_tolerance;
  timing_.solver_iterations = 0;
  timing_.solver_passes = 0;
  const int max_passes = std::max(1, options_.point_linearizations_per_update);
  if (!solver_workspace_) solver_workspace_ = std::make_unique<internal::WindowSolverWorkspace>();
  for (int pass = 0; pass < max_passes; ++pass) {
    const internal::WindowSolverSummary summary = internal::SolveWindowPass(
        (*build)->problem.get(), (*build)->relinearized, solver_options, solver_workspace_.get());
    timing_.solver_iterations += summary.iterations;
    ++timing_.solver_passes;
    for (auto& kf : window_) kf->state.q_W_I.normalize();
    if (pass + 1 == max_passes) break;
    // Tolerance 0: every group relinearized by every pass.
    std::optional<std::vector<double>> motions;
    if (options_.relinearization_tolerance_m > 0.0) {
      motions = PointGroupMotions();
      if (std::all_of(motions->begin(), motions->end(),
                      [this](double m) { return m <= options_.relinearization_tolerance_m; })) {
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
  if (!options_.smoothing) {
    return Marginalize(build->problem.get(), blocks, options_.marginalization);
  }
  MarginalConditional conditional;
  std::unique_ptr<MarginalizationPrior> prior =
      Marginalize(build->problem.get(), blocks, options_.marginalization, &conditional);
  RecordSmoothingStep(std::move(conditional));
  return prior;
}

CalibrationCovariance SlidingWindowEstimator::ComputeCalibrationCovariance(
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
