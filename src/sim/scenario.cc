#include "autocal/sim/scenario.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <unordered_map>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"

namespace autocal {
namespace sim {
namespace {

constexpr double kKmh = 1.0 / 3.6;

// Lateral offset of the drive from the lane it started in: about the sum of the lane changes
// up to s (smooth within each change). Roadside objects subtract it to follow the road
// rather than the drive.
struct LaneOffsets {
  struct Shift {
    double s_begin, s_end, shift_m;
  };
  std::vector<Shift> shifts;

  double operator()(double s) const {
    double offset = 0.0;
    for (const Shift& shift : shifts) {
      if (s >= shift.s_end) {
        offset += shift.shift_m;
      } else if (s > shift.s_begin) {
        offset += shift.shift_m * SmoothStep((s - shift.s_begin) / (shift.s_end - shift.s_begin));
      }
    }
    return offset;
  }
};

// Plans path and speed in lock step: every piece of distance appears in both.
class DriveBuilder {
 public:
  DriveBuilder(double heading_rad, double initial_speed_m_s)
      : path_(Eigen::Vector2d::Zero(), heading_rad), speed_(initial_speed_m_s) {}

  double time_s() const { return speed_.end_time_s(); }
  double distance_m() const { return path_.length_m(); }

  void Cruise(double length_m) {
    path_.AddStraight(length_m);
    speed_.Hold(length_m / RequireMoving());
  }
  // Smooth-step speed change with the given peak acceleration magnitude, on a straight.
  void ChangeSpeed(double target_m_s, double peak_accel_m_s2) {
    const double v0 = speed_.final_speed_m_s();
    if (std::abs(target_m_s - v0) < 1e-9) return;
    const double duration = kSmoothStepPeakSlope * std::abs(target_m_s - v0) / peak_accel_m_s2;
    speed_.ChangeSpeed(target_m_s, duration);
    path_.AddStraight(0.5 * (v0 + target_m_s) * duration);
  }
  void Stand(double duration_s) {
    if (speed_.final_speed_m_s() != 0.0) throw Error("simulated drive: standing while moving");
    speed_.Hold(duration_s);
  }
  void Arc(double heading_change_rad, double radius_m, double ramp_m) {
    const double length = std::abs(heading_change_rad) * radius_m + ramp_m;
    path_.AddArc(heading_change_rad, radius_m, ramp_m);
    speed_.Hold(length / RequireMoving());
  }
  // A turn on the spot while standing (skid steer), over duration_s.
  void Pivot(double heading_change_rad, double duration_s) {
    if (speed_.final_speed_m_s() != 0.0) throw Error("simulated drive: pivoting while moving");
    pivots_.Add(time_s(), duration_s, heading_change_rad);
    speed_.Hold(duration_s);
    path_.AddPivot(heading_change_rad);
  }
  void LaneChange(double shift_m, double length_m) {
    const double s0 = path_.length_m();
    path_.AddLaneChange(shift_m, length_m);
    speed_.Hold(length_m / RequireMoving());
    lane_offsets_.shifts.push_back({s0, s0 + length_m, shift_m});
  }

  const LaneOffsets& lane_offsets() const { return lane_offsets_; }

  PathProfile& path() { return path_; }
  SpeedProfile& speed() { return speed_; }
  const PivotProfile& pivots() const { return pivots_; }

 private:
  double RequireMoving() const {
    const double v = speed_.final_speed_m_s();
    if (!(v > 0.1)) throw Error("simulated drive: a path piece needs the vehicle moving");
    return v;
  }
  PathProfile path_;
  SpeedProfile speed_;
  PivotProfile pivots_;
  LaneOffsets lane_offsets_;
};

// A grade profile over [-extent, extent]: constant grades drawn from +-max_grade, joined by
// transitions of the given width range.
GradeProfile RandomGrades(std::mt19937_64* rng, double extent_m, double max_grade, double min_gap_m,
                          double max_gap_m, double min_width_m, double max_width_m) {
  std::uniform_real_distribution<double> grade(-max_grade, max_grade);
  std::uniform_real_distribution<double> gap(min_gap_m, max_gap_m);
  std::uniform_real_distribution<double> width(min_width_m, max_width_m);
  std::vector<GradeProfile::Transition> transitions;
  double u = -extent_m;
  double current = grade(*rng);
  while (u < extent_m) {
    GradeProfile::Transition tr;
    tr.u_begin = u + gap(*rng);
    tr.u_end = tr.u_begin + width(*rng);
    tr.grade_before = current;
    tr.grade_after = current = grade(*rng);
    transitions.push_back(tr);
    u = tr.u_end;
  }
  return GradeProfile(std::move(transitions));
}

// Path samples in a coarse grid, to keep placed objects off the road.
class Corridor {
 public:
  Corridor(const PathProfile& path, double s_begin, double s_end) {
    for (double s = s_begin; s <= s_end; s += 1.0) {
      const Eigen::Vector2d p = path.Position(s);
      cells_[Key(p)].push_back(p);
    }
  }
  // True if the footprint (centre, yaw, half length/width) keeps `clearance` from the path.
  bool IsClear(const Eigen::Vector2d& center, double yaw, double half_length, double half_width,
               double clearance) const {
    const double reach = std::hypot(half_length, half_width) + clearance;
    const int cells = static_cast<int>(std::ceil(reach / kCell));
    const auto [cx, cy] = Key(center);
    const double c = std::cos(yaw), s = std::sin(yaw);
    for (int dx = -cells; dx <= cells; ++dx) {
      for (int dy = -cells; dy <= cells; ++dy) {
        const auto it = cells_.find({cx + dx, cy + dy});
        if (it == cells_.end()) continue;
        for (const Eigen::Vector2d& p : it->second) {
          const Eigen::Vector2d d = p - center;
          const double along = std::abs(c * d.x() + s * d.y()) - half_length;
          const double across = std::abs(-s * d.x() + c * d.y()) - half_width;
          if (std::hypot(std::max(along, 0.0), std::max(across, 0.0)) < clearance) return false;
        }
      }
    }
    return true;
  }

 private:
  static constexpr double kCell = 10.0;
  struct PairHash {
    size_t operator()(const std::pair<int, int>& k) const {
      // The two cells' bit patterns side by side (shifted as unsigned: a negative int may
      // not be shifted left).
      const uint64_t bits = (static_cast<uint64_t>(static_cast<uint32_t>(k.first)) << 32) |
                            static_cast<uint32_t>(k.second);
      return std::hash<int64_t>()(static_cast<int64_t>(bits));
    }
  };
  static std::pair<int, int> Key(const Eigen::Vector2d& p) {
    return {static_cast<int>(std::floor(p.x() / kCell)),
            static_cast<int>(std::floor(p.y() / kCell))};
  }
  std::unordered_map<std::pair<int, int>, std::vector<Eigen::Vector2d>, PairHash> cells_;
};

// Places objects beside the drive.
class Placer {
 public:
  Placer(const VehicleTrajectory& trajectory, const Corridor& corridor, World* world)
      : trajectory_(trajectory), corridor_(corridor), world_(world) {}

  // A box of size (length along the path, width across, height) whose centre is lateral_m
  // to the left of the path at s, resting on the ground (sunk 1 m so slopes leave no gap).
  bool AddBox(double s, double lateral_m, const Eigen::Vector3d& size, double extra_yaw,
              double clearance, float reflectivity, double base_above_ground_m = 0.0) {
    const double yaw = trajectory_.path().Heading(s) + extra_yaw;
    const Eigen::Vector3d ground = trajectory_.GroundPointBeside(s, lateral_m);
    if (!corridor_.IsClear(ground.head<2>(), yaw, 0.5 * size.x(), 0.5 * size.y(), clearance)) {
      return false;
    }
    const double sink = base_above_ground_m > 0.0 ? 0.0 : 1.0;
    Box box;
    box.half_extents_m = 0.5 * Eigen::Vector3d(size.x(), size.y(), size.z() + sink);
    box.T_W_O = geometry::Pose3d(
        Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())),
        ground + Eigen::Vector3d(0, 0, base_above_ground_m - sink + box.half_extents_m.z()));
    box.reflectivity = reflectivity;
    world_->AddBox(box);
    return true;
  }

  bool AddPole(double s, double lateral_m, double radius_m, double height_m, double clearance,
               float reflectivity) {
    const Eigen::Vector3d ground = trajectory_.GroundPointBeside(s, lateral_m);
    if (!corridor_.IsClear(ground.head<2>(), 0.0, radius_m, radius_m, clearance)) return false;
    Cylinder c;
    c.center_xy = ground.head<2>();
    c.radius_m = radius_m;
    c.z_min_m = ground.z() - 0.5;
    c.z_max_m = ground.z() + height_m;
    c.reflectivity = reflectivity;
    world_->AddCylinder(c);
    return true;
  }

  // A vehicle moving along the drive's path: arc length s(t), lateral offset lateral(s),
  // heading reversed for oncoming traffic.
  void AddVehicle(std::function<double(double)> s_of_t, std::function<double(double)> lateral_of_s,
                  const Eigen::Vector3d& size, bool oncoming, float reflectivity,
                  std::shared_ptr<const VehicleTrajectory> trajectory) {
    MovingBox box;
    box.half_extents_m = 0.5 * size;
    box.reflectivity = reflectivity;
    const double half_height = box.half_extents_m.z();
    box.pose_W_O = [trajectory, s_of_t, lateral_of_s, half_height,
                    oncoming](double t) -> geometry::Pose3d {
      const double s = s_of_t(t);
      const Eigen::Vector3d ground = trajectory->GroundPointBeside(s, lateral_of_s(s));
      const double yaw = trajectory->path().Heading(s) + (oncoming ? M_PI : 0.0);
      return geometry::Pose3d(Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ())),
                              ground + Eigen::Vector3d(0, 0, half_height + 0.15));
    };
    world_->AddMovingBox(std::move(box));
  }

 private:
  const VehicleTrajectory& trajectory_;
  const Corridor& corridor_;
  World* world_;
};

struct Island {
  double s;
  double radius_m;
};

struct ParkedObstacle {
  double s;
  double lateral_m;
};

}  // namespace

std::string ScenarioName(ScenarioType type) {
  switch (type) {
    case ScenarioType::kUrban:
      return "urban";
    case ScenarioType::kHighway:
      return "highway";
    case ScenarioType::kSkidSteer:
      return "skid_steer";
    case ScenarioType::kStraight:
      return "straight";
  }
  return "unknown";
}

ScenarioType ParseScenarioType(const std::string& name) {
  for (ScenarioType type : {ScenarioType::kUrban, ScenarioType::kHighway, ScenarioType::kSkidSteer,
                            ScenarioType::kStraight}) {
    if (name == ScenarioName(type)) return type;
  }
  throw Error("unknown scenario '" + name + "' (expected urban, highway, skid_steer or straight)");
}

namespace {

Scenario BuildUrban(const ScenarioOptions& options, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  auto between = [&](double a, double b) { return a + (b - a) * uniform(*rng); };
  const double heading = 0.5 * M_PI * static_cast<int>(between(0.0, 4.0));
  DriveBuilder drive(heading, 0.0);
  const double v_cruise = between(38.0, 46.0) * kKmh;
  std::vector<Island> islands;
  std::vector<ParkedObstacle> obstacles;

  // A standstill first (initialization needs one), then away.
  drive.Stand(1.5);
  drive.ChangeSpeed(v_cruise, 3.0);
  // The roundabout and a stop come first, so that a one-minute log has all the excitation.
  enum Maneuver {
    kRoundabout,
    kStopLeftTurn,
    kRightTurn,
    kOvertake,
    kStopStraight,
    kLeftTurn,
    kStopRightTurn,
    kNumManeuvers
  };
  for (int m = 0; drive.time_s() < options.duration_s + 5.0; ++m) {
    drive.Cruise(between(15.0, 35.0));
    const double v_turn = between(16.0, 20.0) * kKmh;
    const Maneuver maneuver = static_cast<Maneuver>(m % kNumManeuvers);
    switch (maneuver) {
      case kRightTurn:
      case kLeftTurn:
        drive.ChangeSpeed(v_turn, 2.5);
        drive.Arc((maneuver == kRightTurn ? -90.0 : 90.0) * kDegToRad, between(9.0, 11.0), 10.0);
        break;
      case kStopLeftTurn:
      case kStopRightTurn:
        drive.ChangeSpeed(0.0, 3.0);
        drive.Stand(between(2.0, 3.0));
        drive.ChangeSpeed(v_turn, 1.5);
        drive.Arc((maneuver == kStopLeftTurn ? 90.0 : -90.0) * kDegToRad, between(9.0, 11.0), 10.0);
        break;
      case kRoundabout: {  // third exit: -35 + 160 - 35 = +90 degrees
        drive.ChangeSpeed(v_turn, 2.5);
        drive.Arc(-35.0 * kDegToRad, 14.0, 8.0);
        const double radius = 14.0;
        const double s0 = drive.distance_m();
        drive.Arc(160.0 * kDegToRad, radius, 8.0);
        // The middle of the symmetric arc is on its circle: the island is R to the left.
        islands.push_back({0.5 * (s0 + drive.distance_m()), radius});
        drive.Arc(-35.0 * kDegToRad, 14.0, 8.0);
        break;
      }
      case kOvertake: {  // around a car parked in the lane
        const double shift = 2.8;
        drive.LaneChange(shift, 50.0);
        obstacles.push_back({drive.distance_m() + 6.0, -shift});
        drive.Cruise(12.0);
        drive.LaneChange(-shift, 50.0);
        break;
      }
      case kStopStraight:  // a crossing, straight on
        drive.ChangeSpeed(0.0, 3.0);
        drive.Stand(between(2.0, 3.5));
        break;
      case kNumManeuvers:
        break;
    }
    drive.ChangeSpeed(v_cruise, 2.5);
  }
  drive.Cruise(50.0);

  const double extent = drive.distance_m() + 400.0;
  auto ground =
      std::make_shared<GroundSurface>(RandomGrades(rng, extent, 0.04, 60.0, 160.0, 40.0, 70.0),
                                      RandomGrades(rng, extent, 0.04, 60.0, 160.0, 40.0, 70.0));
  auto trajectory =
      std::make_shared<VehicleTrajectory>(drive.path(), drive.speed(), ground, options.dynamics);
  auto world = std::make_shared<World>(ground);
  const double s_end = drive.distance_m() + 150.0;
  const Corridor corridor(trajectory->path(), -60.0, s_end);
  Placer placer(*trajectory, corridor, world.get());

  for (const Island& island : islands) {
    const Eigen::Vector3d center = trajectory->GroundPointBeside(island.s, island.radius_m);
    world->AddCylinder(
        {center.head<2>(), island.radius_m - 4.5, center.z() - 0.5, center.z() + 0.8, 0.4f});
    world->AddCylinder({center.head<2>(), 0.4, center.z(), center.z() + 7.0, 0.5f});
  }
  for (const ParkedObstacle& o : obstacles) {
    placer.AddBox(o.s, o.lateral_m, {4.5, 1.8, 1.5}, 0.0, 0.8, 0.7f, 0.2);
  }
  for (double s = -50.0; s < s_end; s += between(14.0, 28.0)) {
    for (double side : {-1.0, 1.0}) {
      const Eigen::Vector3d size(between(12.0, 26.0), between(8.0, 16.0), between(6.0, 25.0));
      const double lateral = side * (between(9.0, 12.0) + 0.5 * size.y());
      placer.AddBox(s, lateral, size, 0.0, 7.0, static_cast<float>(between(0.3, 0.8)));
    }
  }
  for (double s = -40.0; s < s_end; s += between(18.0, 35.0)) {
    const double side = uniform(*rng) < 0.5 ? -1.0 : 1.0;
    placer.AddPole(s, side * between(5.5, 6.5), between(0.1, 0.2), between(5.0, 9.0), 3.5, 0.6f);
  }
  for (double s = -30.0; s < s_end; s += between(7.0, 20.0)) {
    if (uniform(*rng) < 0.45) {
      placer.AddBox(s, -between(3.6, 4.0), {4.5, 1.8, 1.5}, between(-0.05, 0.05), 2.2, 0.7f, 0.2);
    }
  }
  // Oncoming traffic in the opposite lane.
  for (int k = 0; k < 4; ++k) {
    const double s_start = 90.0 + 150.0 * k + between(0.0, 60.0);
    const double speed = between(8.0, 12.0);
    placer.AddVehicle([s_start, speed](double t) { return s_start - speed * t; },
                      [](double) { return 4.2; }, {4.5, 1.8, 1.5}, true, 0.7f, trajectory);
  }

  Scenario scenario;
  scenario.type = ScenarioType::kUrban;
  scenario.ground = ground;
  scenario.trajectory = trajectory;
  scenario.world = world;
  scenario.limits = {50.0 * kKmh, 0.0, 4.0, 5.0};
  return scenario;
}

Scenario BuildHighway(const ScenarioOptions& options, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  auto between = [&](double a, double b) { return a + (b - a) * uniform(*rng); };
  const double v_initial = between(115.0, 125.0) * kKmh;
  DriveBuilder drive(between(-M_PI, M_PI), v_initial);
  constexpr double kLane = 3.7;
  int lane = 0;  // -1 right, 0 middle, +1 left
  for (int m = 0; drive.time_s() < options.duration_s + 5.0; ++m) {
    drive.Cruise(between(60.0, 160.0));
    switch (m % 4) {
      case 0:
      case 2: {  // lane change, staying on the three-lane road
        const int target = lane == 0 ? (uniform(*rng) < 0.5 ? -1 : 1) : 0;
        drive.LaneChange((target - lane) * kLane, between(200.0, 260.0));
        lane = target;
        break;
      }
      case 1: {  // gentle curve
        const double sign = uniform(*rng) < 0.5 ? -1.0 : 1.0;
        drive.Arc(sign * between(7.0, 12.0) * kDegToRad, between(900.0, 1500.0), 120.0);
        break;
      }
      case 3:  // speed change with the traffic
        drive.ChangeSpeed(between(110.0, 128.0) * kKmh, 0.8);
        break;
    }
  }
  drive.Cruise(200.0);

  const double extent = drive.distance_m() + 600.0;
  auto ground =
      std::make_shared<GroundSurface>(RandomGrades(rng, extent, 0.03, 200.0, 500.0, 150.0, 250.0),
                                      RandomGrades(rng, extent, 0.03, 200.0, 500.0, 150.0, 250.0));
  auto trajectory =
      std::make_shared<VehicleTrajectory>(drive.path(), drive.speed(), ground, options.dynamics);
  auto world = std::make_shared<World>(ground);
  const double s_end = drive.distance_m() + 300.0;
  const Corridor corridor(trajectory->path(), -150.0, s_end);
  Placer placer(*trajectory, corridor, world.get());
  // Lateral position of the road's middle lane relative to the drive.
  auto road = [lanes = drive.lane_offsets()](double s) { return -lanes(s); };

  for (double s = -120.0; s < s_end; s += 16.0) {  // noise barriers, with gaps
    for (double side : {-1.0, 1.0}) {
      if (uniform(*rng) < 0.15) continue;
      placer.AddBox(s, road(s) + side * 9.5, {16.0, 0.4, 3.5}, 0.0, 2.0, 0.5f);
    }
  }
  for (double s = -120.0; s < s_end; s += between(40.0, 60.0)) {  // lamp posts
    placer.AddPole(s, road(s) - 11.0, 0.15, 10.0, 2.0, 0.6f);
  }
  for (double s = 0.0; s < s_end; s += between(250.0, 400.0)) {  // sign gantries
    placer.AddPole(s, road(s) + 11.0, 0.3, 7.5, 2.0, 0.6f);
    placer.AddPole(s, road(s) - 11.0, 0.3, 7.5, 2.0, 0.6f);
    placer.AddBox(s, road(s), {1.0, 22.0, 1.5}, 0.0, 0.0, 0.8f, 6.0);
  }
  for (double s = -150.0; s < s_end; s += between(15.0, 40.0)) {  // trees and buildings
    const double side = uniform(*rng) < 0.5 ? -1.0 : 1.0;
    if (uniform(*rng) < 0.7) {
      placer.AddPole(s, road(s) + side * between(14.0, 30.0), between(0.3, 0.6), between(6.0, 12.0),
                     4.0, 0.4f);
    } else {
      placer.AddBox(s, road(s) + side * between(25.0, 45.0),
                    {between(10.0, 30.0), between(8.0, 15.0), between(5.0, 15.0)}, 0.0, 10.0, 0.5f);
    }
  }
  // The lead vehicle keeps a varying gap in the drive's own lane; others in adjacent lanes.
  auto ego_s = [trajectory](double t) { return trajectory->ArcLengthAt(t); };
  placer.AddVehicle([ego_s](double t) { return ego_s(t) + 32.0 + 6.0 * std::sin(0.37 * t); },
                    [](double) { return 0.0; }, {4.6, 1.9, 1.5}, false, 0.7f, trajectory);
  const double v_left = between(34.0, 38.0), v_truck = between(23.0, 26.0);
  placer.AddVehicle([v_left](double t) { return -40.0 + v_left * t; },
                    [road](double s) { return road(s) + kLane; }, {4.6, 1.9, 1.5}, false, 0.7f,
                    trajectory);
  placer.AddVehicle([v_truck](double t) { return 90.0 + v_truck * t; },
                    [road](double s) { return road(s) - kLane; }, {12.0, 2.5, 3.8}, false, 0.6f,
                    trajectory);

  Scenario scenario;
  scenario.type = ScenarioType::kHighway;
  scenario.ground = ground;
  scenario.trajectory = trajectory;
  scenario.world = world;
  scenario.limits = {130.0 * kKmh, 100.0 * kKmh, 2.5, 3.0};
  return scenario;
}

// One lap of the skid-steer loop: two identical halves, each a straight ending in a pivot by
// +90 deg and a straight ending in a +90 deg arc. The second half is the first rotated by
// 180 deg, so every lap closes on itself. The first half starts with a pivot to the right
// and back (turns on the spot in both directions, no displacement).
void SkidSteerLap(DriveBuilder* drive, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  auto between = [&](double a, double b) { return a + (b - a) * uniform(*rng); };
  const double side_a = between(28.0, 40.0), side_b = between(18.0, 26.0);
  const double v_fast = between(0.8, 1.0), v_slow = between(0.4, 0.6);
  const double radius = between(2.0, 3.0), accel = 0.4;
  const double wiggle = between(45.0, 75.0) * kDegToRad;
  for (int half = 0; half < 2; ++half) {
    if (half == 0) {
      drive->Pivot(-wiggle, 4.0);
      drive->Stand(0.5);
      drive->Pivot(wiggle, 4.0);
      drive->Stand(0.5);
    }
    // Side a: away, half of it fast and half slow, stop, pivot left.
    const double start = drive->distance_m();
    drive->ChangeSpeed(v_fast, accel);
    drive->Cruise(0.5 * side_a);
    drive->ChangeSpeed(v_slow, accel);
    drive->Cruise(side_a - (drive->distance_m() - start) -
                  0.5 * v_slow * v_slow / (accel / kSmoothStepPeakSlope));
    drive->ChangeSpeed(0.0, accel);
    drive->Stand(1.0);
    drive->Pivot(0.5 * M_PI, 5.0);
    drive->Stand(1.0);
    // Side b, then a slow arc to the left without stopping.
    drive->ChangeSpeed(v_fast, accel);
    drive->Cruise(side_b);
    drive->ChangeSpeed(v_slow, accel);
    drive->Arc(0.5 * M_PI, radius, 1.5);
    drive->ChangeSpeed(0.0, accel);
    drive->Stand(1.0);
  }
}

// Trees and sheds scattered around the drive, clear of it.
void AddOpenGroundObjects(Placer* placer, double s_begin, double s_end, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  auto between = [&](double a, double b) { return a + (b - a) * uniform(*rng); };
  for (double s = s_begin; s < s_end; s += between(4.0, 9.0)) {
    const double side = uniform(*rng) < 0.5 ? -1.0 : 1.0;
    if (uniform(*rng) < 0.8) {
      placer->AddPole(s, side * between(4.0, 15.0), between(0.1, 0.4), between(3.0, 10.0), 2.0,
                      0.4f);
    } else {
      placer->AddBox(s, side * between(8.0, 20.0),
                     {between(3.0, 8.0), between(3.0, 6.0), between(2.5, 4.0)}, between(-0.5, 0.5),
                     3.0, 0.6f);
    }
  }
}

Scenario BuildSkidSteer(const ScenarioOptions& options, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  DriveBuilder drive(-M_PI + 2.0 * M_PI * uniform(*rng), 0.0);
  drive.Stand(2.0);
  while (drive.time_s() < options.duration_s + 5.0) SkidSteerLap(&drive, rng);

  const double extent = 300.0;
  auto ground =
      std::make_shared<GroundSurface>(RandomGrades(rng, extent, 0.03, 15.0, 40.0, 8.0, 15.0),
                                      RandomGrades(rng, extent, 0.03, 15.0, 40.0, 8.0, 15.0));
  auto trajectory = std::make_shared<VehicleTrajectory>(drive.path(), drive.speed(), ground,
                                                        options.dynamics, drive.pivots());
  auto world = std::make_shared<World>(ground);
  // Objects beside the first 250 m (every lap starts at the same point), kept clear of the
  // whole drive: later laps are drawn anew and pass elsewhere.
  const Corridor corridor(trajectory->path(), -5.0, drive.distance_m() + 5.0);
  Placer placer(*trajectory, corridor, world.get());
  AddOpenGroundObjects(&placer, -5.0, std::min(drive.distance_m(), 250.0), rng);

  Scenario scenario;
  scenario.type = ScenarioType::kSkidSteer;
  scenario.ground = ground;
  scenario.trajectory = trajectory;
  scenario.world = world;
  scenario.limits = {1.0, 0.0, 1.0, 2.0};
  return scenario;
}

// A straight road at one heading: away from a standstill, then speed changes between 30 and
// 90 km/h with a stop in every third (the first within a minute). Buildings and poles line
// the road.
Scenario BuildStraight(const ScenarioOptions& options, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  auto between = [&](double a, double b) { return a + (b - a) * uniform(*rng); };
  DriveBuilder drive(between(-M_PI, M_PI), 0.0);
  drive.Stand(2.0);
  drive.ChangeSpeed(between(45.0, 55.0) * kKmh, 2.5);
  for (int m = 0; drive.time_s() < options.duration_s + 5.0; ++m) {
    drive.Cruise(between(30.0, 80.0));
    switch (m % 3) {
      case 0:
        drive.ChangeSpeed(between(65.0, 90.0) * kKmh, between(1.5, 2.5));
        break;
      case 1:
        drive.ChangeSpeed(0.0, 2.8);
        drive.Stand(between(2.0, 3.0));
        drive.ChangeSpeed(between(30.0, 50.0) * kKmh, 2.5);
        break;
      default:
        drive.ChangeSpeed(between(50.0, 80.0) * kKmh, between(1.5, 2.5));
        break;
    }
  }
  drive.Cruise(100.0);

  const double extent = drive.distance_m() + 400.0;
  auto ground =
      std::make_shared<GroundSurface>(RandomGrades(rng, extent, 0.04, 80.0, 200.0, 50.0, 90.0),
                                      RandomGrades(rng, extent, 0.04, 80.0, 200.0, 50.0, 90.0));
  auto trajectory =
      std::make_shared<VehicleTrajectory>(drive.path(), drive.speed(), ground, options.dynamics);
  auto world = std::make_shared<World>(ground);
  const double s_end = drive.distance_m() + 150.0;
  const Corridor corridor(trajectory->path(), -60.0, s_end);
  Placer placer(*trajectory, corridor, world.get());
  for (double s = -50.0; s < s_end; s += between(14.0, 30.0)) {
    for (double side : {-1.0, 1.0}) {
      const Eigen::Vector3d size(between(12.0, 26.0), between(8.0, 16.0), between(6.0, 20.0));
      placer.AddBox(s, side * (between(10.0, 14.0) + 0.5 * size.y()), size, 0.0, 7.0,
                    static_cast<float>(between(0.3, 0.8)));
    }
  }
  for (double s = -40.0; s < s_end; s += between(20.0, 40.0)) {
    const double side = uniform(*rng) < 0.5 ? -1.0 : 1.0;
    placer.AddPole(s, side * between(5.5, 7.0), between(0.1, 0.2), between(5.0, 9.0), 3.5, 0.6f);
  }

  Scenario scenario;
  scenario.type = ScenarioType::kStraight;
  scenario.ground = ground;
  scenario.trajectory = trajectory;
  scenario.world = world;
  scenario.limits = {95.0 * kKmh, 0.0, 3.0, 5.0};
  return scenario;
}

}  // namespace

Scenario BuildScenario(const ScenarioOptions& options) {
  if (!(options.duration_s > 0.0) || options.duration_s > 3600.0) {
    throw Error("simulated scenario: duration must be in (0, 3600] s, got " +
                std::to_string(options.duration_s));
  }
  std::mt19937_64 rng(options.seed * 0x9E3779B97F4A7C15ull + 17);
  switch (options.type) {
    case ScenarioType::kUrban:
      return BuildUrban(options, &rng);
    case ScenarioType::kHighway:
      return BuildHighway(options, &rng);
    case ScenarioType::kSkidSteer:
      return BuildSkidSteer(options, &rng);
    case ScenarioType::kStraight:
      return BuildStraight(options, &rng);
  }
  throw Error("simulated scenario: unknown type");
}

}  // namespace sim
}  // namespace autocal
