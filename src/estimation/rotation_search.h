#pragma once

// The LiDAR-IMU rotation's starting value when no motion checked the nominal one
// (docs/estimation.md, "A rotation no motion checked", Eq. P13). A rotation error eps moves
// the points of two sweeps d apart by about eps x d; the batch's pairing reaches a gate of a
// few decimetres, so from a nominal rotation degrees off, sweeps metres apart (a highway's
// keyframes) pair only what the error leaves near its planes, and the solve stays where it
// started. The search scores rotations about the two axes across the direction of travel
// (a rotation about it moves nothing) by the residual points of consecutive keyframes that
// find a plane within the gate, each weighted by how near, on a grid whose step moves the
// points by one gate.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "autocal/estimation/keyframe.h"
#include "autocal/estimation/lidar_inertial_batch.h"
#include "autocal/estimation/pairing_options.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace estimation {
namespace internal {

struct RotationSearchOptions {
  double range_rad = 0.0;  // candidates within +-range_rad about each axis of the nominal
  int scored_pairs = 16;   // pairs of consecutive keyframes, spread over the log (those the
                           // car moved between are scored)
  int num_threads = 1;
};

// Searches about calibration.q_I_L (out.q_I_L_start: the best) with the keyframes' states and the
// sweeps' pairing (PairingOptions, at the solve's finest coarse level: twice the fine gate).
// Deterministic whatever options.num_threads.
StartingRotationSearch SearchStartingRotation(const sensors::ImuSamples& imu,
                                              const std::vector<SelectedSweep>& sweeps,
                                              const std::vector<Keyframe>& keyframes,
                                              const sensors::Calibration& calibration,
                                              const Eigen::Vector3d& g_W,
                                              const PairingOptions& pairing,
                                              const RotationSearchOptions& options);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
