#pragma once

// The simulator's true keyframe state at an IMU time: the test oracle of the estimators.

#include <algorithm>
#include <cstdint>

#include "autocal/estimation/keyframe.h"
#include "autocal/sim/simulator.h"

namespace autocal {
namespace test {

// The true state at IMU time t_ns, interpolated in the simulator's IMU-rate truth (slerp for
// the rotation, linear for position and velocity; clamped at the ends), with the biases of
// the sample before it.
inline estimation::Keyframe TrueKeyframe(const sim::ImuLog& log, int64_t t_ns) {
  const auto& truth = log.truth;
  auto it = std::lower_bound(truth.begin(), truth.end(), t_ns,
                             [](const io::TrajectorySample& s, int64_t t) { return s.t_ns < t; });
  const size_t i1 = std::min(static_cast<size_t>(it - truth.begin()), truth.size() - 1);
  const size_t i0 = i1 == 0 ? 0 : i1 - 1;
  const double s = i1 == i0 ? 0.0
                            : static_cast<double>(t_ns - truth[i0].t_ns) /
                                  static_cast<double>(truth[i1].t_ns - truth[i0].t_ns);
  estimation::Keyframe kf;
  kf.t_ns = t_ns;
  kf.q_W_I = truth[i0].T_W_I.q.slerp(s, truth[i1].T_W_I.q);
  kf.p_W_I = (1.0 - s) * truth[i0].T_W_I.p + s * truth[i1].T_W_I.p;
  kf.v_W_I = (1.0 - s) * truth[i0].v_W_I + s * truth[i1].v_W_I;
  kf.b_g = log.gyro_bias[i0];
  kf.b_a = log.accel_bias[i0];
  return kf;
}

}  // namespace test
}  // namespace autocal
