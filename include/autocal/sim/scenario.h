#pragma once

// Driving scenarios after the course's coverage analysis (course §1.3.1, §1.3.2):
//   highway: ~120 km/h, gentle curves, lane changes, speed changes, a lead vehicle and
//            traffic in the adjacent lanes, noise barriers, lamp posts, sign gantries;
//   urban:   <= 50 km/h, a standstill at the start, 90-degree turns at intersections (some
//            after a stop), a roundabout, overtaking a parked car, road grades, building
//            facades, poles, parked cars and oncoming traffic;
//   skid_steer: a slow ground robot (<= 1 m/s) on open ground, laps of a closed loop of a
//            few minutes with turns on the spot (pivots) and tight arcs, a few trees and
//            sheds (a LiDAR is optional there);
//   straight: a car on a straight road at one constant heading, with speed changes and a
//            stop (the weak-excitation case of a calibration drive).
// The drive and the world are generated from a seed; the same seed gives the same scenario.

#include <cstdint>
#include <memory>
#include <string>

#include "autocal/sim/ground.h"
#include "autocal/sim/trajectory.h"
#include "autocal/sim/world.h"

namespace autocal {
namespace sim {

enum class ScenarioType { kUrban, kHighway, kSkidSteer, kStraight };

// "urban" / "highway" / "skid_steer" / "straight".
std::string ScenarioName(ScenarioType type);
// Inverse of ScenarioName; throws autocal::Error on an unknown name.
ScenarioType ParseScenarioType(const std::string& name);

struct ScenarioOptions {
  ScenarioType type = ScenarioType::kUrban;
  // The drive is planned at least this long (it continues at constant speed afterwards).
  double duration_s = 60.0;
  uint64_t seed = 1;
  VehicleDynamicsOptions dynamics;
};

// Bounds the scenario's drive respects (checked by the tests), for the V origin.
struct DriveLimits {
  double max_speed_m_s = 0.0;
  double min_cruise_speed_m_s = 0.0;  // highway: slowest speed of the drive
  double max_horizontal_accel_m_s2 = 0.0;
  double max_jerk_m_s3 = 0.0;
};

struct Scenario {
  ScenarioType type = ScenarioType::kUrban;
  std::shared_ptr<const GroundSurface> ground;
  std::shared_ptr<const VehicleTrajectory> trajectory;
  // Moving objects hold a reference to the trajectory's path; keep the two together.
  std::shared_ptr<const World> world;
  DriveLimits limits;
};

Scenario BuildScenario(const ScenarioOptions& options);

}  // namespace sim
}  // namespace autocal
