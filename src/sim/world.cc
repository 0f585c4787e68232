#include "autocal/sim/world.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "autocal/common/error.h"

namespace autocal {
namespace sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Ground: solve f(r) = o_z + r d_z - G(o_xy + r d_xy) = 0 by Newton's method from the sensor
// (f(0) > 0). The grades are gentle and smooth, so f is close to linear and Newton converges
// in a few steps; a ray that does not descend relative to the local slope misses.
bool RaycastGround(const GroundSurface& ground, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                   double max_range_m, double* range, Eigen::Vector3d* normal) {
  double r = 0.0;
  for (int iteration = 0; iteration < 30; ++iteration) {
    const double x = o.x() + r * d.x(), y = o.y() + r * d.y();
    const double f = o.z() + r * d.z() - ground.Height(x, y);
    if (iteration == 0 && f <= 0.0) return false;  // the sensor is under the ground
    const Eigen::Vector2d grad = ground.Gradient(x, y);
    const double slope = d.z() - grad.x() * d.x() - grad.y() * d.y();
    if (slope >= 0.0) return false;
    const double step = -f / slope;
    r += step;
    if (r > 1.5 * max_range_m) return false;
    if (std::abs(step) < 1e-10 * std::max(1.0, r)) {
      if (r > max_range_m) return false;
      const Eigen::Vector2d g = ground.Gradient(o.x() + r * d.x(), o.y() + r * d.y());
      *range = r;
      *normal = Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
      return true;
    }
  }
  return false;
}

// Slab test in the box frame. Returns the entry distance (> 0) and the face normal in W.
bool RaycastBox(const Eigen::Matrix3d& R_O_W, const Eigen::Vector3d& p_W_O,
                const Eigen::Vector3d& half, const Eigen::Vector3d& o_W, const Eigen::Vector3d& d_W,
                double* range, Eigen::Vector3d* normal) {
  const Eigen::Vector3d o = R_O_W * (o_W - p_W_O);
  const Eigen::Vector3d d = R_O_W * d_W;
  double t_near = -kInf, t_far = kInf;
  int axis = -1;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d(i)) < 1e-12) {
      if (std::abs(o(i)) > half(i)) return false;
      continue;
    }
    double t1 = (-half(i) - o(i)) / d(i);
    double t2 = (half(i) - o(i)) / d(i);
    if (t1 > t2) std::swap(t1, t2);
    if (t1 > t_near) {
      t_near = t1;
      axis = i;
    }
    t_far = std::min(t_far, t2);
    if (t_near > t_far) return false;
  }
  if (axis < 0 || t_near <= 0.0) return false;  // parallel to every slab, or inside the box
  Eigen::Vector3d n_O = Eigen::Vector3d::Zero();
  n_O(axis) = d(axis) > 0.0 ? -1.0 : 1.0;
  *range = t_near;
  *normal = R_O_W.transpose() * n_O;
  return true;
}

// Side of a vertical cylinder (its caps are never seen from a car: a ray reaching a cap from
// below meets the side first).
bool RaycastCylinder(const Cylinder& c, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                     double* range, Eigen::Vector3d* normal) {
  const Eigen::Vector2d o2 = o.head<2>() - c.center_xy;
  const Eigen::Vector2d d2 = d.head<2>();
  const double a = d2.squaredNorm();
  if (a < 1e-18) return false;
  const double b = o2.dot(d2);
  const double cc = o2.squaredNorm() - c.radius_m * c.radius_m;
  if (cc <= 0.0) return false;  // inside
  const double disc = b * b - a * cc;
  if (disc < 0.0) return false;
  const double r = (-b - std::sqrt(disc)) / a;
  if (r <= 0.0) return false;
  const double z = o.z() + r * d.z();
  if (z < c.z_min_m || z > c.z_max_m) return false;
  const Eigen::Vector2d radial = (o2 + r * d2) / c.radius_m;
  *range = r;
  *normal = Eigen::Vector3d(radial.x(), radial.y(), 0.0);
  return true;
}

double DistanceToBox(const Eigen::Matrix3d& R_O_W, const Eigen::Vector3d& p_W_O,
                     const Eigen::Vector3d& half, const Eigen::Vector3d& p_W) {
  const Eigen::Vector3d q = (R_O_W * (p_W - p_W_O)).cwiseAbs();
  const Eigen::Vector3d outside = (q - half).cwiseMax(0.0);
  if (outside.squaredNorm() > 0.0) return outside.norm();
  return (half - q).minCoeff();
}

double DistanceToCylinder(const Cylinder& c, const Eigen::Vector3d& p) {
  const double radial = (p.head<2>() - c.center_xy).norm() - c.radius_m;
  const double below = c.z_min_m - p.z(), above = p.z() - c.z_max_m;
  const double dz = std::max({below, above, 0.0});
  if (dz == 0.0) {
    return radial > 0.0 ? radial : std::min({-radial, -below, -above});
  }
  return radial > 0.0 ? std::hypot(radial, dz) : dz;
}

// Keeps the nearer of two hits.
void Consider(double range, const Eigen::Vector3d& normal, float reflectivity, SurfaceKind kind,
              RayHit* best) {
  if (range < best->range_m) {
    best->range_m = range;
    best->normal_W = normal;
    best->reflectivity = reflectivity;
    best->kind = kind;
  }
}

bool Finish(double min_range_m, double max_range_m, RayHit* best, RayHit* hit) {
  if (best->kind == SurfaceKind::kNone || best->range_m < min_range_m ||
      best->range_m > max_range_m) {
    return false;
  }
  *hit = *best;
  return true;
}

int AzimuthBin(double azimuth, int bins) {
  const int b = static_cast<int>(std::floor((azimuth + M_PI) / (2.0 * M_PI) * bins));
  return ((b % bins) + bins) % bins;
}

}  // namespace

World::World(std::shared_ptr<const GroundSurface> ground) : ground_(std::move(ground)) {
  if (!ground_) throw Error("simulated world: no ground surface");
}

bool World::Raycast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double min_range_m,
                    double max_range_m, double t_s, RayHit* hit) const {
  RayHit best;
  best.range_m = kInf;
  double r;
  Eigen::Vector3d n;
  if (RaycastGround(*ground_, origin, dir, max_range_m, &r, &n)) {
    Consider(r, n, 0.3f, SurfaceKind::kGround, &best);
  }
  for (const Box& box : boxes_) {
    if (RaycastBox(box.T_W_O.R().transpose(), box.T_W_O.p, box.half_extents_m, origin, dir, &r,
                   &n)) {
      Consider(r, n, box.reflectivity, SurfaceKind::kBox, &best);
    }
  }
  for (const Cylinder& c : cylinders_) {
    if (RaycastCylinder(c, origin, dir, &r, &n)) {
      Consider(r, n, c.reflectivity, SurfaceKind::kCylinder, &best);
    }
  }
  for (const MovingBox& box : moving_boxes_) {
    const geometry::Pose3d T_W_O = box.pose_W_O(t_s);
    if (RaycastBox(T_W_O.R().transpose(), T_W_O.p, box.half_extents_m, origin, dir, &r, &n)) {
      Consider(r, n, box.reflectivity, SurfaceKind::kMovingBox, &best);
    }
  }
  return Finish(min_range_m, max_range_m, &best, hit);
}

double World::DistanceToSurface(const Eigen::Vector3d& p, double t_s) const {
  double best = std::abs(p.z() - ground_->Height(p.x(), p.y()));
  for (const Box& box : boxes_) {
    best = std::min(best,
                    DistanceToBox(box.T_W_O.R().transpose(), box.T_W_O.p, box.half_extents_m, p));
  }
  for (const Cylinder& c : cylinders_) best = std::min(best, DistanceToCylinder(c, p));
  for (const MovingBox& box : moving_boxes_) {
    const geometry::Pose3d T_W_O = box.pose_W_O(t_s);
    best = std::min(best, DistanceToBox(T_W_O.R().transpose(), T_W_O.p, box.half_extents_m, p));
  }
  return best;
}

SweepRaycaster::SweepRaycaster(const World& world, const Eigen::Vector3d& sensor_begin_W,
                               const Eigen::Vector3d& sensor_end_W, double t_begin_s,
                               double t_end_s, double max_range_m)
    : world_(world), bins_(kAzimuthBins) {
  const Eigen::Vector2d center = 0.5 * (sensor_begin_W + sensor_end_W).head<2>();
  // Any sensor position of the sweep lies within `margin` of the centre (straight-line
  // travel plus a metre for the curvature of the path within 0.1 s).
  const double margin = 0.5 * (sensor_end_W - sensor_begin_W).norm() + 1.0;

  // Adds an object with bounding circle (xy, radius) to every azimuth bin it may occupy.
  auto add = [&](const Eigen::Vector2d& xy, double radius, int code) {
    const Eigen::Vector2d delta = xy - center;
    const double distance = delta.norm();
    const double reach = radius + margin;
    if (distance - reach > max_range_m) return false;
    if (distance <= reach) {
      for (auto& bin : bins_) bin.push_back(code);
      return true;
    }
    const double azimuth = std::atan2(delta.y(), delta.x());
    const double half_angle = std::asin(reach / distance);
    const int first =
        static_cast<int>(std::floor((azimuth - half_angle + M_PI) / (2.0 * M_PI) * kAzimuthBins));
    const int last =
        static_cast<int>(std::floor((azimuth + half_angle + M_PI) / (2.0 * M_PI) * kAzimuthBins));
    for (int b = first; b <= last; ++b) {
      bins_[((b % kAzimuthBins) + kAzimuthBins) % kAzimuthBins].push_back(code);
    }
    return true;
  };

  for (const Box& box : world.boxes_) {
    PreparedBox prepared{box.T_W_O.R().transpose(), box.T_W_O.p,      box.half_extents_m,
                         box.half_extents_m.norm(), box.reflectivity, SurfaceKind::kBox};
    if (add(box.T_W_O.p.head<2>(), box.half_extents_m.norm(), static_cast<int>(boxes_.size()))) {
      boxes_.push_back(prepared);
    }
  }
  for (size_t i = 0; i < world.cylinders_.size(); ++i) {
    const Cylinder& c = world.cylinders_[i];
    if (add(c.center_xy, c.radius_m, -1 - static_cast<int>(cylinders_.size()))) {
      cylinders_.push_back(static_cast<int>(i));
    }
  }
  for (size_t i = 0; i < world.moving_boxes_.size(); ++i) {
    const MovingBox& box = world.moving_boxes_[i];
    const Eigen::Vector3d a = box.pose_W_O(t_begin_s).p, b = box.pose_W_O(t_end_s).p;
    const double reach = box.half_extents_m.norm() + margin + (b - a).norm();
    const Eigen::Vector2d middle = 0.5 * (a + b).head<2>();
    if ((middle - center).norm() - reach <= max_range_m) {
      moving_indices_.push_back(static_cast<int>(i));
    }
  }
  moving_boxes_.resize(moving_indices_.size());
  SetTime(t_begin_s);
}

void SweepRaycaster::SetTime(double t_s) {
  for (size_t k = 0; k < moving_indices_.size(); ++k) {
    const MovingBox& box = world_.moving_boxes_[moving_indices_[k]];
    const geometry::Pose3d T_W_O = box.pose_W_O(t_s);
    moving_boxes_[k] =
        PreparedBox{T_W_O.R().transpose(),     T_W_O.p,          box.half_extents_m,
                    box.half_extents_m.norm(), box.reflectivity, SurfaceKind::kMovingBox};
  }
}

bool SweepRaycaster::MayHit(const PreparedBox& box, const Eigen::Vector3d& origin,
                            const Eigen::Vector3d& dir, double max_range_m) {
  const Eigen::Vector3d to_center = box.p_W_O - origin;
  const double along = to_center.dot(dir);
  const double r = box.bounding_radius_m;
  if (along + r < 0.0 || along - r > max_range_m) return false;
  return to_center.squaredNorm() - along * along <= r * r;
}

bool SweepRaycaster::Raycast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                             double min_range_m, double max_range_m, RayHit* hit) const {
  RayHit best;
  best.range_m = kInf;
  double r;
  Eigen::Vector3d n;
  if (RaycastGround(*world_.ground_, origin, dir, max_range_m, &r, &n)) {
    Consider(r, n, 0.3f, SurfaceKind::kGround, &best);
  }
  const int bin = AzimuthBin(std::atan2(dir.y(), dir.x()), kAzimuthBins);
  for (int code : bins_[bin]) {
    if (code >= 0) {
      const PreparedBox& box = boxes_[code];
      // Only a surface nearer than the best hit so far can matter.
      if (!MayHit(box, origin, dir, std::min(best.range_m, max_range_m))) continue;
      if (RaycastBox(box.R_O_W, box.p_W_O, box.half_extents_m, origin, dir, &r, &n)) {
        Consider(r, n, box.reflectivity, box.kind, &best);
      }
    } else {
      const Cylinder& c = world_.cylinders_[cylinders_[-1 - code]];
      if (RaycastCylinder(c, origin, dir, &r, &n)) {
        Consider(r, n, c.reflectivity, SurfaceKind::kCylinder, &best);
      }
    }
  }
  for (const PreparedBox& box : moving_boxes_) {
    if (!MayHit(box, origin, dir, std::min(best.range_m, max_range_m))) continue;
    if (RaycastBox(box.R_O_W, box.p_W_O, box.half_extents_m, origin, dir, &r, &n)) {
      Consider(r, n, box.reflectivity, box.kind, &best);
    }
  }
  return Finish(min_range_m, max_range_m, &best, hit);
}

}  // namespace sim
}  // namespace autocal
