#pragma once

// Sweep pairing (docs/estimation.md, Eq. P6-P9; docs/sliding_window.md, "Pairing points with
// planes" and "Reuse between updates"): the residual points of a LiDAR sweep paired with planes of
// other sweeps, the points of sweep k on planes of sweep j forming one group factor.
//
// One engine with two passes over the same parts (point selection, deskew into W, the sweeps'
// LiDAR poses, the order in which a point tries its partners, PairingOptions). The batch pairs
// every sweep afresh at each outer iteration (PairEverySweep). The window pairs again at every
// update, so SweepPairing keeps explicit state between updates: per sweep its plane map
// (rebuilt only when its deskew moved), per keyframe its points' partners, tries (kept while
// the relative pose holds) and misses, and the groups' storage (PointGroupPool).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "autocal/estimation/imu_motion_table.h"
#include "autocal/estimation/lidar_inertial_batch.h"
#include "autocal/estimation/pairing_options.h"
#include "autocal/factors/loss.h"
#include "autocal/factors/point_to_sweep_plane_factor.h"
#include "autocal/geometry/se3.h"
#include "autocal/lidar/plane_map.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/imu_preintegration.h"
#include "estimation/point_group_pool.h"

namespace autocal {
namespace estimation {
namespace internal {

// ---------------------------------------------------------------------------------------------
// Shared by the batch and the window.

// The points of a sweep that become residuals and those that build its plane map.
struct SweepSelection {
  std::vector<int> residual_points;
  std::vector<int> map_points;
};
SweepSelection SelectSweepPoints(const lidar::PointCloud& cloud, const PairingOptions& setting);

// The LiDAR pose of a sweep at its reference instant (point time 0) under the current
// estimate: T_W_L = T_W_I(t) T_I_L, T_W_I(t) from Eq. P1-P3 at delta = 0.
geometry::Pose3d SweepLidarPose(const Keyframe& kf, const factors::PointMotion& m,
                                const Eigen::Vector3d& g_W, const Eigen::Quaterniond& q_I_L,
                                const Eigen::Vector3d& p_I_L);

// The points `indices` of a keyframe's sweep in W at the current estimate (Eq. P1-P4 at
// delta = 0), `table` the sweep's motion from its keyframe.
Eigen::Matrix3Xd SweepPointsInWorld(const ImuMotionTable& table, const Keyframe& kf,
                                    const lidar::LidarSweep& sweep, const std::vector<int>& indices,
                                    const Eigen::Vector3d& g_W, const sensors::Calibration& c);
// The same for a reduced sweep, `indices` into its points.
Eigen::Matrix3Xd SweepPointsInWorld(const ImuMotionTable& table, const Keyframe& kf,
                                    const SelectedSweep& sweep, const std::vector<int>& indices,
                                    const Eigen::Vector3d& g_W, const sensors::Calibration& c);

// Eq. W1: the largest displacement of a point within `range_m` of the origin between the
// poses `before` and `after` of its frame, |dp| + angle(dq) range_m with (dq, dp) = before^-1
// after.
double MaxPointMotion(const geometry::Pose3d& before, const geometry::Pose3d& after,
                      double range_m);

// The a-th of P partner positions that residual point r tries: the first S in rotation
// (o_{(r + a) mod S}), then the other P - S likewise. S = P rotates all of them.
inline size_t PartnerPosition(size_t r, size_t a, size_t S, size_t P) {
  return a < S ? (r + a) % S : S + (r + a - S) % (P - S);
}

// ---------------------------------------------------------------------------------------------
// The batch's pass: every sweep paired afresh at each outer iteration, no state kept between
// calls. Plane map j holds sweep j's map points and those of its map_neighbor_sweeps
// neighbours on each side, deskewed into W (a denser local map, whose parts are too close in
// time to disagree much); maps are built for a stretch of sweeps at a time and dropped once
// no later point reaches them, so that a long log never holds them all.

// The sweeps at one estimate: their IMU motion tables from their keyframes and their LiDAR
// poses at the reference instant (point time 0).
struct SweepsAtEstimate {
  const std::vector<SelectedSweep>* sweeps = nullptr;
  const std::vector<Keyframe>* keyframes = nullptr;  // one per sweep
  const sensors::Calibration* calibration = nullptr;
  Eigen::Vector3d g_W = Eigen::Vector3d::Zero();
  std::vector<std::optional<ImuMotionTable>> tables;
  std::vector<factors::PointMotion> reference_motion;
  std::vector<geometry::Pose3d> T_W_L;

  int num_sweeps() const { return static_cast<int>(sweeps->size()); }
};

// A residual point's measurement and the sweep whose plane it lies on (Eq. P6).
struct Association {
  factors::PointToSweepPlaneMeasurement measurement;
  int partner;
};

// Per sweep its points' associations: each residual point on the first plane within the gate
// among its partners, tried in the order of pairing.partner_offsets from a different start for
// consecutive points (PartnerPosition), so that every sweep is tied to sweeps before and after
// it, then in the order of pairing.fallback_partner_offsets.
std::vector<std::vector<Association>> PairEverySweep(const SweepsAtEstimate& at,
                                                     const PairingOptions& pairing,
                                                     int map_neighbor_sweeps, int num_threads);

// The pairing of a coarse-to-fine step: planes `coarse` times thicker, points that much
// noisier and a gate that much wider, so that a calibration still far off finds planes at all.
PairingOptions CoarsePairing(PairingOptions pairing, double coarse);

// ---------------------------------------------------------------------------------------------
// The window's pairing engine and its state.

// A window sweep's residual points: coordinates, times and ranges in their order (contiguous
// for the pairing, which visits them in turn).
struct ResidualPoints {
  std::vector<int> indices;  // in the sweep
  Eigen::Matrix3Xd p_L;
  std::vector<double> time_s;
  std::vector<double> ranges_m;
  double max_range_m = 0.0;
  size_t size() const { return indices.size(); }
};

// A sweep's plane map in its LiDAR frame at the reference instant (point time 0), and the
// sweep's motion in that frame to its point farthest from the stamp, T_L0_L(tau_max), it was
// deskewed with (Eq. W1).
struct SweepMap {
  std::unique_ptr<lidar::PlaneMap> planes;
  geometry::Pose3d deskew_end;
  double max_range_m = 0.0;
  int generation = 0;  // counts the map's builds
};

// What a keyframe's pairing keeps between updates.
struct PairingState {
  // Per residual point the position in partner_offsets of its partner (-1: none).
  std::vector<int> partner_position;
  // Per residual point its plane lookups in a row that found no plane (max_plane_misses),
  // counted since the map generation misses_map_generation.
  std::vector<uint8_t> plane_misses;
  int misses_map_generation = -1;
  // How many partner positions its points try: all when the extrinsic was still
  // converging at its first pairing, settled_partner_count when it had settled.
  size_t partner_walk = 0;
  // Per partner position q the relative poses T_Lj_Lk the points were tried at, with the
  // generations of both sweeps' maps then, and per residual point r and q the index in
  // tries[q] of its last try, tried_at[r * P + q] (-1: not tried since it last mattered).
  struct Try {
    geometry::Pose3d T_Lj_Lk;
    int map_generation = 0;
    int partner_map_generation = 0;
  };
  std::vector<std::vector<Try>> tries;
  std::vector<int> tried_at;
  // Per partner position q < partner_walk, whether its sweep was in the window at the last
  // pairing, and which of tries[q] some point referred to then.
  std::vector<bool> partner_present;
  std::vector<std::vector<uint8_t>> tries_in_use;
};

// One window keyframe with a sweep as the pairing sees it.
struct PairingSweep {
  int id = 0;  // keyframe id: partners are the keyframes id + offset
  Keyframe* state = nullptr;
  const lidar::LidarSweep* sweep = nullptr;
  SweepSpan span;
  const ResidualPoints* residuals = nullptr;
  const std::vector<int>* map_points = nullptr;
  SweepMap* map = nullptr;
  PairingState* pairing = nullptr;
  std::vector<SweepPointGroup>* groups = nullptr;
};

// What one update's pairing depends on besides the sweeps.
struct PairingUpdate {
  const sensors::ImuSamples* imu = nullptr;  // covers every keyframe and its sweep
  Eigen::Vector3d g_W = Eigen::Vector3d::Zero();
  sensors::Calibration* calibration = nullptr;  // the groups' q_I_L, p_I_L, time offset
  // The rotation of q_I_L over the last window_size updates, and whether there were that
  // many (the gate and the settled walk).
  double recent_rotation_rad = 0.0;
  bool full_history = false;
};

struct PairingResult {
  int plane_lookups = 0;           // k-NN plane lookups
  bool extrinsic_settled = false;  // new keyframes try settled_partner_count partners
};

class SweepPairing {
 public:
  SweepPairing(const PairingOptions& pairing, const WindowPairingOptions& window,
               const factors::LossOptions& point_loss, int num_threads);

  // Refreshes the plane maps whose deskew moved and makes the tries that are missing or
  // stale; rebuilds the point groups whose points changed.
  PairingResult Pair(const std::vector<PairingSweep>& sweeps, const PairingUpdate& update);

  // The groups' storage, for the groups the window drops.
  PointGroupPool& pool() { return pool_; }

 private:
  PairingOptions pairing_;
  WindowPairingOptions window_;
  factors::LossOptions point_loss_;
  int num_threads_;
  PointGroupPool pool_;
};

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
