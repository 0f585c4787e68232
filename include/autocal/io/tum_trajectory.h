#pragma once

// TUM RGB-D trajectory format, as read by evo (`evo_ape tum ...`):
//   # timestamp tx ty tz qx qy qz qw
//   1700000000.123456789 1.5 -2.25 0.5 0 0 0.7071067811865476 0.7071067811865476
// one pose per line, blank-separated; the timestamp in seconds printed with all nine
// decimals so that the nanosecond stamp reads back exactly; the pose is T_W_I (p_W_I and
// q_W_I, Hamilton [qx qy qz qw]). Velocities are not part of the format: they read back as
// zero. Lines starting with '#' are comments. Stamps read exactly, without a detour through
// double, in decimal or in scientific notation (evo writes "%.18e":
// 1.403636579763555527e+09); digits finer than a nanosecond round to the nearest one.
//
// A file written here states that it is whole, in comments other TUM readers skip: its first
// line is "# autocal_trajectory_1 timestamp tx ty tz qx qy qz qw" and its last "# end: <N>
// poses" followed by a line break. ReadTumTrajectory refuses such a file when the end line is
// missing, counts other than the poses read, or is not the last line: a trajectory cut while
// it was written is never read as a shorter one. Files from other tools (no such first line)
// are read as they are, but one without any pose is refused.

#include <string>

#include "autocal/io/dataset.h"

namespace autocal {
namespace io {

// Writes to a temporary file renamed into place (io/output_files.h). Throws autocal::Error on
// I/O failure, a non-finite value or non-increasing stamps.
void WriteTumTrajectory(const std::string& path, const Trajectory& trajectory);

// Throws ParseError (file, line, column) on a malformed line, a quaternion whose norm is off
// 1 by more than 1e-3, non-increasing timestamps, an empty file or a cut one (see above);
// quaternions are normalized.
Trajectory ReadTumTrajectory(const std::string& path);

}  // namespace io
}  // namespace autocal
