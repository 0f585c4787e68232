#pragma once

// Does a sensor rig see what its driving needs? The course's coverage analysis (§1.3) as
// code (docs/coverage.md): braking and following distances from a scenario's speed and
// decelerations, the regions each manoeuvre must see around the vehicle, and which sensors,
// mounted where they are, see them past the vehicle's own body.
//
// Frame: the vehicle's, x forward, y left, z up, origin on the ground under the rear axle
// (Autoware's base_link). Angles in radians, lengths in metres.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace autocal {
namespace coverage {

// ---- The scenario and its distances ----

struct Scenario {
  std::string name;
  double speed_m_s = 0.0;
  double aggressive_deceleration_m_s2 = 5.0;  // an emergency stop (course, Remark 1.1)
  double normal_deceleration_m_s2 = 2.0;      // a comfortable stop
  double reaction_time_s = 0.0;               // of the automated system
  double lane_width_m = 3.7;                  // North America
  double time_gap_s = 2.0;                    // the nominal following gap
  double side_range_m = 60.0;                 // adjacent lanes, ahead and beside (40-60 m)
  double rear_range_m = 60.0;                 // behind, for lane changes
  double overtake_time_s = 5.0;               // to pass a parked car
  double omni_range_m = 50.0;                 // all around, at intersections
  double roundabout_range_m = 30.0;           // all around, in roundabouts
  double target_height_m = 0.5;               // of the points a sensor must see
  double min_covered_fraction = 0.99;         // of a region, to call it covered
  // Any of emergency_stop, maintain_speed, lane_change, overtake, intersection, roundabout.
  std::vector<std::string> maneuvers;
};

// Eq. (1) of the course: d = v^2 / (2 a).
double BrakingDistanceM(double speed_m_s, double deceleration_m_s2);
// The emergency stop's range: v t_r + v^2 / (2 a_aggressive) (Eq. V1).
double EmergencyStopRangeM(const Scenario& s);
// Following (Eq. V2): the lead vehicle stops at the aggressive rate while the ego vehicle,
// after its reaction time, stops at the normal rate; the gap that avoids a collision,
// v t_r + v^2 / (2 a_normal) - v^2 / (2 a_aggressive), or the time gap v t_gap if longer.
double FollowingRangeM(const Scenario& s);
// Overtaking a parked car: the oncoming lane over the time the pass takes, both vehicles at
// the scenario's speed: 2 v t_overtake (Eq. V3).
double OncomingRangeM(const Scenario& s);

// ---- The rig ----

enum class SensorType { kLidar, kCamera, kRadar, kUltrasonic };
const char* SensorTypeName(SensorType type);

struct Sensor {
  std::string name;
  SensorType type = SensorType::kLidar;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  double yaw_rad = 0.0;       // of the optical axis, from forward towards left
  double pitch_rad = 0.0;     // of the optical axis, positive down
  double hfov_rad = 0.0;      // full horizontal field of view (2 pi: all around)
  double vfov_min_rad = 0.0;  // lowest elevation seen, relative to the optical axis
  double vfov_max_rad = 0.0;
  double range_m = 0.0;
  double min_range_m = 0.0;
};

// The ego vehicle as a box that blocks the sensors' view: x from rear to front, |y| up to
// half_width, z from the ground to the height.
struct Body {
  double rear_m = -1.0;
  double front_m = 3.8;
  double half_width_m = 0.9;
  double height_m = 1.5;
};

struct Rig {
  std::string name;
  Body body;
  std::vector<Sensor> sensors;
};

// Whether `sensor` sees the point `target` (in range, inside both fields of view, the line of
// sight not through the body).
bool Sees(const Sensor& sensor, const Body& body, const Eigen::Vector3d& target);

// ---- Requirements and the analysis ----

// A region of the ground a manoeuvre must see, as a polygon (counter-clockwise, x-y).
struct Region {
  std::string name;         // "own lane ahead"
  std::string requirement;  // "0-111 m ahead, 3.7 m wide"
  std::vector<Eigen::Vector2d> polygon;
};

struct Maneuver {
  std::string name;  // "emergency_stop"
  std::vector<Region> regions;
};

// The regions of every manoeuvre the scenario lists; throws autocal::Error on an unknown
// manoeuvre or a non-positive speed, deceleration or range.
std::vector<Maneuver> Requirements(const Scenario& scenario, const Body& body);

struct RegionCoverage {
  Region region;
  int samples = 0;
  double covered_fraction = 0.0;
  // Per sensor, the share of the region it sees (in rig order).
  std::vector<double> sensor_fraction;
  // The uncovered sample farthest from the rear axle: range and bearing (rad).
  double worst_range_m = 0.0;
  double worst_bearing_rad = 0.0;
  // How far past the region the view reaches in its weakest direction: over the region's
  // corners, the least distance that stays seen beyond the corner on the ray from the
  // vehicle's centre (capped at 100 m; 0 when the corner itself is not seen).
  double margin_m = 0.0;
  bool covered = false;
};

struct ManeuverCoverage {
  std::string name;
  std::vector<RegionCoverage> regions;
  bool covered = false;
};

// Samples each region on a grid (about `samples_per_region` points at the scenario's target
// height) and tests every sensor on each.
std::vector<ManeuverCoverage> AnalyzeCoverage(const Rig& rig, const Scenario& scenario,
                                              int samples_per_region = 2000);

// A table: manoeuvre, region, requirement, covered share, verdict, the sensors that see it.
std::string CoverageTable(const Rig& rig, const std::vector<ManeuverCoverage>& result);
// A top view (SVG): the body, each sensor's wedge, each required region outlined (green
// covered, red short).
std::string CoverageSvg(const Rig& rig, const std::vector<ManeuverCoverage>& result);

}  // namespace coverage
}  // namespace autocal
