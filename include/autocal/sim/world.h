#pragma once

// The simulated world the LiDAR sees: the ground height field, static boxes (building
// facades, parked cars, barriers, gantries), vertical cylinders (poles, trees, roundabout
// islands) and moving boxes (other vehicles, each on its own trajectory). Ray casting is
// analytic per shape; SweepRaycaster culls the world once per sweep by range and azimuth so
// that a ray only meets the few objects that can lie in its direction.

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "autocal/geometry/se3.h"
#include "autocal/sim/ground.h"

namespace autocal {
namespace sim {

enum class SurfaceKind : uint8_t { kNone, kGround, kBox, kCylinder, kMovingBox };

// A box with centre and orientation T_W_O (frame O at the centre) and half extents.
struct Box {
  geometry::Pose3d T_W_O;
  Eigen::Vector3d half_extents_m = Eigen::Vector3d::Ones();
  float reflectivity = 0.5f;  // in [0, 1]
};

// A vertical cylinder (z up) standing between z_min_m and z_max_m.
struct Cylinder {
  Eigen::Vector2d center_xy = Eigen::Vector2d::Zero();
  double radius_m = 0.15;
  double z_min_m = 0.0;
  double z_max_m = 6.0;
  float reflectivity = 0.5f;
};

// A box that moves: T_W_O(t) at drive time t (seconds).
struct MovingBox {
  std::function<geometry::Pose3d(double t_s)> pose_W_O;
  Eigen::Vector3d half_extents_m = Eigen::Vector3d::Ones();
  float reflectivity = 0.5f;
};

struct RayHit {
  double range_m = 0.0;
  Eigen::Vector3d normal_W = Eigen::Vector3d::UnitZ();  // unit, facing the ray origin
  float reflectivity = 0.0f;
  SurfaceKind kind = SurfaceKind::kNone;
};

class World {
 public:
  explicit World(std::shared_ptr<const GroundSurface> ground);

  void AddBox(const Box& box) { boxes_.push_back(box); }
  void AddCylinder(const Cylinder& cylinder) { cylinders_.push_back(cylinder); }
  void AddMovingBox(MovingBox box) { moving_boxes_.push_back(std::move(box)); }

  const GroundSurface& ground() const { return *ground_; }
  const std::vector<Box>& boxes() const { return boxes_; }
  const std::vector<Cylinder>& cylinders() const { return cylinders_; }
  const std::vector<MovingBox>& moving_boxes() const { return moving_boxes_; }

  // Nearest hit of origin + r dir (dir unit) with min_range_m <= r <= max_range_m at time
  // t_s, testing every object (the reference; SweepRaycaster is the fast path).
  bool Raycast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double min_range_m,
               double max_range_m, double t_s, RayHit* hit) const;

  // Distance from p to the nearest surface at time t_s (the ground counts vertically, which
  // is zero exactly when p is on it). Used to check that simulated points lie on surfaces.
  double DistanceToSurface(const Eigen::Vector3d& p, double t_s) const;

 private:
  friend class SweepRaycaster;
  std::shared_ptr<const GroundSurface> ground_;
  std::vector<Box> boxes_;
  std::vector<Cylinder> cylinders_;
  std::vector<MovingBox> moving_boxes_;
};

// Casts the rays of one sweep. Built from the sensor positions at the sweep's start and end:
// only objects within reach are kept, binned by the azimuth interval under which they can
// appear from anywhere on the sensor's path during the sweep.
class SweepRaycaster {
 public:
  SweepRaycaster(const World& world, const Eigen::Vector3d& sensor_begin_W,
                 const Eigen::Vector3d& sensor_end_W, double t_begin_s, double t_end_s,
                 double max_range_m);

  // Poses of the moving objects at t_s; call before casting the rays fired at t_s.
  void SetTime(double t_s);

  // Same contract as World::Raycast at the time of the last SetTime.
  bool Raycast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double min_range_m,
               double max_range_m, RayHit* hit) const;

 private:
  static constexpr int kAzimuthBins = 360;
  struct PreparedBox {
    Eigen::Matrix3d R_O_W;
    Eigen::Vector3d p_W_O;
    Eigen::Vector3d half_extents_m;
    double bounding_radius_m;
    float reflectivity;
    SurfaceKind kind;
  };
  // False if the box cannot be hit nearer than max_range_m (bounding-sphere test, far
  // cheaper than the slab test it saves).
  static bool MayHit(const PreparedBox& box, const Eigen::Vector3d& origin,
                     const Eigen::Vector3d& dir, double max_range_m);
  const World& world_;
  std::vector<PreparedBox> boxes_;
  std::vector<int> cylinders_;
  std::vector<int> moving_indices_;
  std::vector<PreparedBox> moving_boxes_;
  // Per azimuth bin: indices into boxes_ (>= 0) or cylinders_ (encoded as -1 - index).
  std::vector<std::vector<int>> bins_;
};

}  // namespace sim
}  // namespace autocal
