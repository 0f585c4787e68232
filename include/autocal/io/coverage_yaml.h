#pragma once

// The coverage tool's inputs (docs/coverage.md): a rig file (the body and the sensors, some
// placed by a calibration.yaml result) and a scenario file, read strictly: every problem is a
// ParseError with the file, line and column.

#include <string>

#include "autocal/coverage/coverage.h"

namespace autocal {
namespace io {

// Reads a rig file. A sensor given `pose_from_calibration: lidar` takes its position, yaw and
// pitch from the calibration file the rig names (T_V_I T_I_L, raised by the rear axle's
// height above the ground: the file's `axle_height_m`, else the mean calibrated rear radius).
coverage::Rig ReadRigYaml(const std::string& path);

// Reads a scenario file (speed in km/h; every other key as coverage::Scenario names it).
coverage::Scenario ReadScenarioYaml(const std::string& path);

// The course's scenarios (§1.3): "highway" (120 km/h; emergency stop, maintain speed, lane
// change) and "urban" (50 km/h; also overtaking, intersections, roundabouts). Throws
// autocal::Error for another name.
coverage::Scenario ScenarioPreset(const std::string& name);

}  // namespace io
}  // namespace autocal
