#pragma once

// How the residual points of a LiDAR sweep are chosen and paired with planes of other sweeps
// (docs/estimation.md, Eq. P6; docs/sliding_window.md, "Pairing points with planes"), shared by
// the batch solver and the sliding window with defaults of their own.

#include <algorithm>
#include <vector>

#include "autocal/lidar/plane_map.h"

namespace autocal {
namespace estimation {

struct PairingOptions {
  // Residual points: one per voxel (in L) between min_range_m and residual_max_range_m, then
  // at most max_residuals_per_sweep, evenly spread (0: no limit, for either).
  double residual_voxel_m = 0.6;
  double residual_max_range_m = 0.0;
  int max_residuals_per_sweep = 400;
  double map_voxel_m = 0.3;          // one plane-map point per voxel of this size
  double min_range_m = 2.0;          // closer points (the car itself) are ignored
  lidar::PlaneMapOptions plane_map;  // local plane fitting in each map
  // Sweep k's points pair with planes of sweep k + offset, tried in this order from a different
  // start for consecutive points: partners that moved, yet still overlap, make the extrinsic
  // and the time offset observable.
  std::vector<int> partner_offsets = {5, -5, 10, -10, 20, -20, 3, -3};
  // Tried in this order by a point that none of partner_offsets paired: the nearest sweeps,
  // whose pairs a wrong extrinsic rotation moves least (by the angle times the distance driven
  // between the sweeps). At highway speed the partners above lie 20 to 130 m down the road, and
  // a LiDAR yaw a few degrees off puts their barrier and kerb points metres from any plane, so
  // the rotation stayed where it started, at a sigma from the pairs that remained (the batch
  // only; the window's own partner list holds its nearest keyframes).
  std::vector<int> fallback_partner_offsets = {1, -1};
  double max_point_to_plane_m = 0.1;  // outlier gate (moving objects, edges, corners)
  double point_sigma_m = 0.03;        // 1-sigma of a point-to-plane distance
};

// The sliding window's pairing between updates (docs/sliding_window.md, "Partner walk" and
// "Reuse between updates").
struct WindowPairingOptions {
  // Points try the first settled_partner_count offsets, then the others; once the extrinsic
  // has settled (q_I_L turned at most settled_extrinsic_deg over window_size updates), a newly
  // paired keyframe's points try only the first ones.
  int settled_partner_count = 2;
  double settled_extrinsic_deg = 0.5;
  // While q_I_L moves the gate widens to max_point_to_plane_m + gate_extrinsic_factor *
  // max(0, angle - gate_extrinsic_free_deg) * r at range r, angle the rotation of q_I_L over
  // the last window_size updates (factor 0: a fixed gate).
  double gate_extrinsic_factor = 0.25;
  double gate_extrinsic_free_deg = 0.5;
  // Lookups without a plane after which a point waits for its sweep's map to be rebuilt (0:
  // never waits; at most 255).
  int max_plane_misses = 6;
  // A try holds while both maps stand and the sweeps' relative pose moved at most
  // reassociation_tolerance_m at the point's range; a map is rebuilt when its deskew moves a
  // point by more than map_rebuild_tolerance_m (0: always).
  double reassociation_tolerance_m = 0.02;
  double map_rebuild_tolerance_m = 0.02;
  bool skip_unchanged_keyframes = true;  // skip walks that would change nothing (same pairs)
};

// The batch solver's defaults: a few hundred points per sweep, partners up to 20 sweeps away.
inline PairingOptions BatchPairingDefaults() { return PairingOptions(); }

// The sliding window's partners for a window of `window_size` keyframes: the farthest keyframe
// pairing reaches on either side first, ±window_size (while it pairs, the window holds the new
// keyframe and the oldest, not yet marginalized), then those 5, 8, 3 and 2 keyframes away that
// are nearer. Once the extrinsic has settled a point walks only the first
// settled_partner_count of them (WindowPairingOptions): pairs across the whole window tie the
// keyframes' roll and pitch over the longest span it holds, where nearer pairs let them drift
// with the biases (docs/sliding_window.md, "Partner walk").
inline std::vector<int> WindowPartnerOffsets(int window_size) {
  const int farthest = std::max(1, window_size);
  std::vector<int> offsets = {-farthest, farthest};
  for (const int o : {5, 8, 3, 2}) {
    if (o < farthest) offsets.insert(offsets.end(), {-o, o});
  }
  return offsets;
}

// The sliding window's defaults for a window of `window_size` keyframes: partners within the
// window, points beyond 40 m dropped (too sparse for a local plane;
// docs/history/sliding_window_notes.md).
inline PairingOptions WindowPairingDefaults(int window_size) {
  PairingOptions s;
  s.residual_max_range_m = 40.0;
  s.max_residuals_per_sweep = 2000;
  s.partner_offsets = WindowPartnerOffsets(window_size);
  s.fallback_partner_offsets.clear();
  return s;
}

}  // namespace estimation
}  // namespace autocal
