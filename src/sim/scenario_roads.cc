// A call takes at most one random draw: several are named first (random_streams.h).
#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "scenario_parts.h"

namespace autocal {
namespace sim {
namespace internal {

namespace {

struct Island {
  double s;
  double radius_m;
};

struct ParkedObstacle {
  double s;
  double lateral_m;
};

}  // namespace

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
  const Scene scene =
      SceneOf(drive, RandomGround(rng, extent, 0.04, 60.0, 160.0, 40.0, 70.0), options.dynamics);
  const auto& trajectory = scene.trajectory;
  const double s_end = drive.distance_m() + 150.0;
  const Corridor corridor(trajectory->path(), -60.0, s_end);
  Placer placer(*trajectory, corridor, scene.world.get());

  for (const Island& island : islands) {
    const Eigen::Vector3d center = trajectory->GroundPointBeside(island.s, island.radius_m);
    scene.world->AddCylinder(
        {center.head<2>(), island.radius_m - 4.5, center.z() - 0.5, center.z() + 0.8, 0.4f});
    scene.world->AddCylinder({center.head<2>(), 0.4, center.z(), center.z() + 7.0, 0.5f});
  }
  for (const ParkedObstacle& o : obstacles) {
    placer.AddBox(o.s, o.lateral_m, {4.5, 1.8, 1.5}, 0.0, 0.8, 0.7f, 0.2);
  }
  for (double s = -50.0; s < s_end; s += between(14.0, 28.0)) {
    for (double side : {-1.0, 1.0}) {
      const double height = between(6.0, 25.0), depth = between(8.0, 16.0),
                   length = between(12.0, 26.0);
      const Eigen::Vector3d size(length, depth, height);
      const double lateral = side * (between(9.0, 12.0) + 0.5 * size.y());
      placer.AddBox(s, lateral, size, 0.0, 7.0, static_cast<float>(between(0.3, 0.8)));
    }
  }
  for (double s = -40.0; s < s_end; s += between(18.0, 35.0)) {
    const double side = uniform(*rng) < 0.5 ? -1.0 : 1.0;
    const double height = between(5.0, 9.0), radius = between(0.1, 0.2),
                 lateral = side * between(5.5, 6.5);
    placer.AddPole(s, lateral, radius, height, 3.5, 0.6f);
  }
  for (double s = -30.0; s < s_end; s += between(7.0, 20.0)) {
    if (uniform(*rng) < 0.45) {
      const double yaw = between(-0.05, 0.05), lateral = -between(3.6, 4.0);
      placer.AddBox(s, lateral, {4.5, 1.8, 1.5}, yaw, 2.2, 0.7f, 0.2);
    }
  }
  // Oncoming traffic in the opposite lane.
  for (int k = 0; k < 4; ++k) {
    const double s_start = 90.0 + 150.0 * k + between(0.0, 60.0);
    const double speed = between(8.0, 12.0);
    placer.AddVehicle([s_start, speed](double t) { return s_start - speed * t; },
                      [](double) { return 4.2; }, {4.5, 1.8, 1.5}, true, 0.7f, trajectory);
  }

  return scene.Of(ScenarioType::kUrban, {50.0 * kKmh, 0.0, 4.0, 5.0});
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
        const double radius = between(900.0, 1500.0), angle = sign * between(7.0, 12.0) * kDegToRad;
        drive.Arc(angle, radius, 120.0);
        break;
      }
      case 3:  // speed change with the traffic
        drive.ChangeSpeed(between(110.0, 128.0) * kKmh, 0.8);
        break;
    }
  }
  drive.Cruise(200.0);

  const double extent = drive.distance_m() + 600.0;
  const Scene scene =
      SceneOf(drive, RandomGround(rng, extent, 0.03, 200.0, 500.0, 150.0, 250.0), options.dynamics);
  const auto& trajectory = scene.trajectory;
  const double s_end = drive.distance_m() + 300.0;
  const Corridor corridor(trajectory->path(), -150.0, s_end);
  Placer placer(*trajectory, corridor, scene.world.get());
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
      const double height = between(6.0, 12.0), radius = between(0.3, 0.6),
                   lateral = road(s) + side * between(14.0, 30.0);
      placer.AddPole(s, lateral, radius, height, 4.0, 0.4f);
    } else {
      const double length = between(10.0, 30.0), depth = between(8.0, 15.0),
                   height = between(5.0, 15.0), lateral = road(s) + side * between(25.0, 45.0);
      placer.AddBox(s, lateral, {length, depth, height}, 0.0, 10.0, 0.5f);
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

  return scene.Of(ScenarioType::kHighway, {130.0 * kKmh, 100.0 * kKmh, 2.5, 3.0});
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
      case 0: {
        const double accel = between(1.5, 2.5), speed = between(65.0, 90.0) * kKmh;
        drive.ChangeSpeed(speed, accel);
        break;
      }
      case 1:
        drive.ChangeSpeed(0.0, 2.8);
        drive.Stand(between(2.0, 3.0));
        drive.ChangeSpeed(between(30.0, 50.0) * kKmh, 2.5);
        break;
      default: {
        const double accel = between(1.5, 2.5), speed = between(50.0, 80.0) * kKmh;
        drive.ChangeSpeed(speed, accel);
        break;
      }
    }
  }
  drive.Cruise(100.0);

  const double extent = drive.distance_m() + 400.0;
  const Scene scene =
      SceneOf(drive, RandomGround(rng, extent, 0.04, 80.0, 200.0, 50.0, 90.0), options.dynamics);
  const auto& trajectory = scene.trajectory;
  const double s_end = drive.distance_m() + 150.0;
  const Corridor corridor(trajectory->path(), -60.0, s_end);
  Placer placer(*trajectory, corridor, scene.world.get());
  for (double s = -50.0; s < s_end; s += between(14.0, 30.0)) {
    for (double side : {-1.0, 1.0}) {
      const double height = between(6.0, 20.0), depth = between(8.0, 16.0),
                   length = between(12.0, 26.0);
      const Eigen::Vector3d size(length, depth, height);
      const double reflectivity = between(0.3, 0.8),
                   lateral = side * (between(10.0, 14.0) + 0.5 * size.y());
      placer.AddBox(s, lateral, size, 0.0, 7.0, static_cast<float>(reflectivity));
    }
  }
  for (double s = -40.0; s < s_end; s += between(20.0, 40.0)) {
    const double side = uniform(*rng) < 0.5 ? -1.0 : 1.0;
    const double height = between(5.0, 9.0), radius = between(0.1, 0.2),
                 lateral = side * between(5.5, 7.0);
    placer.AddPole(s, lateral, radius, height, 3.5, 0.6f);
  }

  return scene.Of(ScenarioType::kStraight, {95.0 * kKmh, 0.0, 3.0, 5.0});
}

}  // namespace internal
}  // namespace sim
}  // namespace autocal
