#pragma once

// Independent, reproducible random streams: each sensor (and each LiDAR sweep) draws from
// its own generator seeded by (seed, stream, index), so that turning one sensor off or
// generating sweeps in any order leaves every other draw unchanged.

#include <Eigen/Core>
#include <cstdint>
#include <random>

namespace autocal {
namespace sim {

// New streams go at the end: the values of the existing ones seed their generators.
enum class Stream : uint32_t {
  kNominal = 1,
  kImu,
  kWheel,
  kGnss,
  kLidar,
  kImuStamps,
  kWheelStamps,
  kWheelForm  // the noise of wheel speeds and odometry twist
};

// C++ leaves the order of a call's arguments open, so no call here takes more than one draw:
// where a call needs several, they are named first, in the order every simulated dataset was
// made with (GCC's for the call they replace: last argument first). DrawVector3(draw) is
// Eigen::Vector3d(draw(), draw(), draw()) in that order: z, then y, then x.
template <typename Draw>
Eigen::Vector3d DrawVector3(Draw&& draw) {
  const double z = draw();
  const double y = draw();
  const double x = draw();
  return Eigen::Vector3d(x, y, z);
}

inline std::mt19937_64 RandomStream(uint64_t seed, Stream stream, uint64_t index = 0) {
  std::seed_seq seq{static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32),
                    static_cast<uint32_t>(stream), static_cast<uint32_t>(index),
                    static_cast<uint32_t>(index >> 32)};
  return std::mt19937_64(seq);
}

}  // namespace sim
}  // namespace autocal
