#pragma once

// Independent, reproducible random streams: each sensor (and each LiDAR sweep) draws from
// its own generator seeded by (seed, stream, index), so that turning one sensor off or
// generating sweeps in any order leaves every other draw unchanged.

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

inline std::mt19937_64 RandomStream(uint64_t seed, Stream stream, uint64_t index = 0) {
  std::seed_seq seq{static_cast<uint32_t>(seed), static_cast<uint32_t>(seed >> 32),
                    static_cast<uint32_t>(stream), static_cast<uint32_t>(index),
                    static_cast<uint32_t>(index >> 32)};
  return std::mt19937_64(seq);
}

}  // namespace sim
}  // namespace autocal
