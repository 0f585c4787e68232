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
      const double height = between(3.0, 10.0), radius = between(0.1, 0.4),
                   lateral = side * between(4.0, 15.0);
      placer->AddPole(s, lateral, radius, height, 2.0, 0.4f);
    } else {
      const double yaw = between(-0.5, 0.5), length = between(3.0, 8.0), depth = between(3.0, 6.0),
                   height = between(2.5, 4.0), lateral = side * between(8.0, 20.0);
      placer->AddBox(s, lateral, {length, depth, height}, yaw, 3.0, 0.6f);
    }
  }
}

}  // namespace

Scenario BuildSkidSteer(const ScenarioOptions& options, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  DriveBuilder drive(-M_PI + 2.0 * M_PI * uniform(*rng), 0.0);
  drive.Stand(2.0);
  while (drive.time_s() < options.duration_s + 5.0) SkidSteerLap(&drive, rng);

  const double extent = 300.0;
  const Scene scene =
      SceneOf(drive, RandomGround(rng, extent, 0.03, 15.0, 40.0, 8.0, 15.0), options.dynamics);
  // Objects beside the first 250 m (every lap starts at the same point), kept clear of the
  // whole drive: later laps are drawn anew and pass elsewhere.
  const Corridor corridor(scene.trajectory->path(), -5.0, drive.distance_m() + 5.0);
  Placer placer(*scene.trajectory, corridor, scene.world.get());
  AddOpenGroundObjects(&placer, -5.0, std::min(drive.distance_m(), 250.0), rng);

  return scene.Of(ScenarioType::kSkidSteer, {1.0, 0.0, 1.0, 2.0});
}

}  // namespace internal
}  // namespace sim
}  // namespace autocal
