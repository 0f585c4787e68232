#pragma once

// The pieces the simulated scenarios are built from (scenario_roads.cc, scenario_skid_steer.cc):
// a drive planned as path and speed together, grades, and objects placed beside the drive
// clear of it; and the builders BuildScenario dispatches to.

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <unordered_map>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/sim/scenario.h"

namespace autocal {
namespace sim {
namespace internal {

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
  // A turn on a circle entered and left through ramps (PathProfile::AddArc). A turn too
  // gentle for its ramps, which alone would turn more than heading_change_rad, gets ramps of
  // |heading_change_rad| radius_m each and no circle between them: it reaches the same
  // curvature and turns by the requested angle.
  void Arc(double heading_change_rad, double radius_m, double ramp_m) {
    ramp_m = std::min(ramp_m, std::abs(heading_change_rad) * radius_m);
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

  const PathProfile& path() const { return path_; }
  const SpeedProfile& speed() const { return speed_; }
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
inline GradeProfile RandomGrades(std::mt19937_64* rng, double extent_m, double max_grade,
                                 double min_gap_m, double max_gap_m, double min_width_m,
                                 double max_width_m) {
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

// Ground whose grade along x and along y are independent RandomGrades with one setting. The
// profile along y is drawn first (the order the simulated datasets were generated with).
inline std::shared_ptr<GroundSurface> RandomGround(std::mt19937_64* rng, double extent_m,
                                                   double max_grade, double min_gap_m,
                                                   double max_gap_m, double min_width_m,
                                                   double max_width_m) {
  GradeProfile along_y =
      RandomGrades(rng, extent_m, max_grade, min_gap_m, max_gap_m, min_width_m, max_width_m);
  GradeProfile along_x =
      RandomGrades(rng, extent_m, max_grade, min_gap_m, max_gap_m, min_width_m, max_width_m);
  return std::make_shared<GroundSurface>(std::move(along_x), std::move(along_y));
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

// What a builder places its objects in: the drive on its ground, and a world holding that
// ground.
struct Scene {
  std::shared_ptr<GroundSurface> ground;
  std::shared_ptr<VehicleTrajectory> trajectory;
  std::shared_ptr<World> world;

  Scenario Of(ScenarioType type, const DriveLimits& limits) const {
    Scenario scenario;
    scenario.type = type;
    scenario.ground = ground;
    scenario.trajectory = trajectory;
    scenario.world = world;
    scenario.limits = limits;
    return scenario;
  }
};

// The drive (with its turns on the spot, if any) on `ground`, the world empty but for it.
inline Scene SceneOf(const DriveBuilder& drive, std::shared_ptr<GroundSurface> ground,
                     const VehicleDynamicsOptions& dynamics) {
  auto trajectory = std::make_shared<VehicleTrajectory>(drive.path(), drive.speed(), ground,
                                                        dynamics, drive.pivots());
  auto world = std::make_shared<World>(ground);
  return {std::move(ground), std::move(trajectory), std::move(world)};
}

// The scenarios of ScenarioType, each drawing from `rng`.
Scenario BuildUrban(const ScenarioOptions& options, std::mt19937_64* rng);
Scenario BuildHighway(const ScenarioOptions& options, std::mt19937_64* rng);
Scenario BuildSkidSteer(const ScenarioOptions& options, std::mt19937_64* rng);
Scenario BuildStraight(const ScenarioOptions& options, std::mt19937_64* rng);

}  // namespace internal
}  // namespace sim
}  // namespace autocal
