#pragma once

// Which of the LiDAR's calibration blocks a solver estimates; the others are held at their
// starting value. Shared by the batch solver (LidarInertialBatchOptions::estimate) and the
// sliding window, whose SlidingWindowEstimatedBlocks adds the wheels' and the antenna's.

namespace autocal {
namespace estimation {

struct LidarEstimatedBlocks {
  bool extrinsic_rotation = true;     // q_I_L
  bool extrinsic_translation = true;  // p_I_L
  bool time_offset = true;            // time_offset_lidar_imu_s
};

}  // namespace estimation
}  // namespace autocal
