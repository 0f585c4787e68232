#pragma once

// The batch solver's association step (docs/estimation.md, Eq. P6): every residual point of a
// sweep paired with a plane of a partner sweep, at one outer iteration's estimate. The plane
// maps are built per stretch of sweeps and dropped once no later point reaches them.

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <vector>

#include "autocal/common/parallel_for.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/estimation/lidar_inertial_batch.h"
#include "autocal/factors/point_to_sweep_plane_factor.h"
#include "autocal/geometry/se3.h"
#include "autocal/lidar/plane_map.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/imu_preintegration.h"

namespace autocal {
namespace estimation {
namespace internal {

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

// The sweeps at one outer iteration's estimate: their IMU motion tables and their LiDAR poses
// at the reference instant.
struct PropagatedSweeps {
  std::vector<std::optional<ImuMotionTable>> tables;
  std::vector<factors::PointMotion> reference_motion;
  std::vector<geometry::Pose3d> T_W_L;
};

// What one outer iteration associated (Eq. P6): per sweep its points' measurements and their
// partner sweeps.
struct Association {
  factors::PointToSweepPlaneMeasurement measurement;
  int partner;
};

// The coarse-to-fine scale of an iteration: the first iterations accept planes 2^(steps -
// iteration) times thicker and points that much noisier, so that a calibration still far off
// finds associations at all.
struct IterationScale {
  lidar::PlaneMapOptions map_options;
  double point_sigma_m;
  double max_point_to_plane_m;
};

// Step 3: each point paired with a plane of another sweep; per sweep its associations.
std::vector<std::vector<Association>> AssociatePoints(const BatchInputs& in,
                                                      const PropagatedSweeps& at,
                                                      const IterationScale& scale);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
