#pragma once

// TUM RGB-D trajectory format, as read by evo (`evo_ape tum ...`):
//   # timestamp tx ty tz qx qy qz qw
//   1700000000.123456789 1.5 -2.25 0.5 0 0 0.7071067811865476 0.7071067811865476
// one pose per line, blank-separated; the timestamp in seconds printed with all nine
// decimals so that the nanosecond stamp reads back exactly; the pose is T_W_I (p_W_I and
// q_W_I, Hamilton [qx qy qz qw]). Velocities are not part of the format: they read back as
// zero. Lines starting with '#' are comments.

#include <string>

#include "autocal/io/dataset.h"

namespace autocal {
namespace io {

// Throws autocal::Error on I/O failure, a non-finite value or non-increasing stamps.
void WriteTumTrajectory(const std::string& path, const Trajectory& trajectory);

// Throws ParseError (file, line, column) on a malformed line, a quaternion whose norm is off
// 1 by more than 1e-3 or non-increasing timestamps; quaternions are normalized.
Trajectory ReadTumTrajectory(const std::string& path);

}  // namespace io
}  // namespace autocal
