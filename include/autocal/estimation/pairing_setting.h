#pragma once

// How the residual points of a LiDAR sweep are chosen and paired with planes of other sweeps
// (docs/estimation.md, Eq. P6; docs/sliding_window.md, "Association"). The batch solver and
// the sliding window share these fields; each starts from its own defaults
// (BatchPairingDefaults, WindowPairingDefaults).

#include <vector>

#include "autocal/lidar/plane_map.h"

namespace autocal {
namespace estimation {

struct PairingSetting {
  // Residual points: one per voxel of this size (in L), none closer than min_range_m or
  // farther than residual_max_range_m (0: no limit), then at most max_residuals_per_sweep
  // (evenly spread; 0: all).
  double residual_voxel_m = 0.6;
  double residual_max_range_m = 0.0;
  int max_residuals_per_sweep = 400;
  // Points that build a sweep's plane map: one per voxel of this size.
  double map_voxel_m = 0.3;
  double min_range_m = 2.0;          // closer points (the car itself) are ignored
  lidar::PlaneMapOptions plane_map;  // local plane fitting in each map
  // A point of sweep k is paired with a plane of sweep k + offset, the offsets tried in this
  // order, starting at a different one for consecutive points. Partners a few sweeps apart
  // have moved relative to the point's sweep, which makes the extrinsic and time offset
  // observable; they must still overlap it.
  std::vector<int> partner_offsets = {5, -5, 10, -10, 20, -20, 3, -3};
  // Outlier gate: a point farther than this from the plane found for it is not paired
  // (moving objects, edges, planes fitted across a corner).
  double max_point_to_plane_m = 0.1;
  double point_sigma_m = 0.03;  // 1-sigma of a point-to-plane distance
};

// The sliding window's pairing between updates (docs/sliding_window.md, "Association" and
// "Reuse between updates"): which partners a point walks, the gate while the extrinsic
// converges, and what is kept from one update to the next.
struct WindowPairingSetting {
  // A point tries the first settled_partner_count offsets first, then the others; the points
  // of a keyframe first paired once the extrinsic rotation has settled (window_size updates
  // made, q_I_L moved by at most settled_extrinsic_deg over them) try only the first ones.
  int settled_partner_count = 2;
  double settled_extrinsic_deg = 0.5;
  // While q_I_L still moves, a point at range r is paired within max_point_to_plane_m +
  // gate_extrinsic_factor * max(0, angle - gate_extrinsic_free_deg) * r of its plane, `angle`
  // the rotation of q_I_L over the last window_size updates (0: a fixed gate).
  double gate_extrinsic_factor = 0.25;
  double gate_extrinsic_free_deg = 0.5;
  // A point whose last max_plane_misses lookups found no plane is not looked up again until
  // its own sweep's map is rebuilt (0: always looked up). At most 255.
  int max_plane_misses = 6;
  // A try (a plane found or none) holds while both maps are unchanged and the sweeps'
  // relative pose moved by at most reassociation_tolerance_m at the point's range; a map is
  // rebuilt when its deskew moves a point by more than map_rebuild_tolerance_m (0: always).
  double reassociation_tolerance_m = 0.02;
  double map_rebuild_tolerance_m = 0.02;
  // Skip a keyframe whose walk would change nothing (false: walk all; the same pairs).
  bool skip_unchanged_keyframes = true;
};

// The batch solver's defaults: a few hundred points per sweep, partners up to 20 sweeps away.
inline PairingSetting BatchPairingDefaults() { return PairingSetting(); }

// The sliding window's defaults: partners within the window, far points dropped (beyond about
// 40 m a 32-beam LiDAR's rings lie a metre apart, too sparse for a local plane).
inline PairingSetting WindowPairingDefaults() {
  PairingSetting s;
  s.residual_max_range_m = 40.0;
  s.max_residuals_per_sweep = 2000;
  s.partner_offsets = {-5, 5, -8, 8, -3, 3, -2, 2};
  return s;
}

}  // namespace estimation
}  // namespace autocal
