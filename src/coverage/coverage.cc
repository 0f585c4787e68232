#include "autocal/coverage/coverage.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/units.h"

namespace autocal {
namespace coverage {
namespace {

constexpr double kTwoPi = 2.0 * M_PI;
constexpr int kDiscSides = 72;

void RequirePositive(double value, const char* what) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw Error(std::string("coverage: ") + what + " must be a positive number");
  }
}

std::string Metres(double v) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(v < 10.0 ? 1 : 0) << v << " m";
  return out.str();
}

// The rectangle x in [x0, x1], y in [y0, y1].
std::vector<Eigen::Vector2d> Box(double x0, double x1, double y0, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

// The disc of `radius` around `centre`.
std::vector<Eigen::Vector2d> Disc(const Eigen::Vector2d& centre, double radius) {
  std::vector<Eigen::Vector2d> polygon;
  for (int k = 0; k < kDiscSides; ++k) {
    const double a = kTwoPi * k / kDiscSides;
    polygon.push_back(centre + radius * Eigen::Vector2d(std::cos(a), std::sin(a)));
  }
  return polygon;
}

bool InsidePolygon(const std::vector<Eigen::Vector2d>& polygon, const Eigen::Vector2d& p) {
  bool inside = false;
  for (size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x()) {
      inside = !inside;
    }
  }
  return inside;
}

bool InsideBody(const Body& body, const Eigen::Vector2d& p) {
  return p.x() >= body.rear_m && p.x() <= body.front_m && std::abs(p.y()) <= body.half_width_m;
}

// Whether the segment from `a` to `b` crosses the body box (slab method). A sensor inside
// the box (behind the windscreen, in a bumper) looks out through the body's surface, and a
// ray from inside a convex box never re-enters it: never blocked. The first 5 cm from `a` are
// left out, so that a sensor mounted on the surface sees out too.
bool ThroughBody(const Body& body, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d lo(body.rear_m, -body.half_width_m, 0.0);
  const Eigen::Vector3d hi(body.front_m, body.half_width_m, body.height_m);
  if ((a.array() >= lo.array()).all() && (a.array() <= hi.array()).all()) return false;
  const Eigen::Vector3d d = b - a;
  const double length = d.norm();
  if (!(length > 0.05)) return false;
  double t0 = 0.05 / length, t1 = 1.0;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d(i)) < 1e-12) {
      if (a(i) < lo(i) || a(i) > hi(i)) return false;
      continue;
    }
    double ta = (lo(i) - a(i)) / d(i), tb = (hi(i) - a(i)) / d(i);
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

double WrapAngle(double a) { return std::remainder(a, kTwoPi); }

Region Lane(const std::string& name, double x0, double x1, double y0, double y1,
            const std::string& what) {
  return {name, what, Box(x0, x1, y0, y1)};
}

// Both adjacent lanes over x in [x0, x1].
std::vector<Region> AdjacentLanes(const std::string& name, double x0, double x1, double lane,
                                  const std::string& what) {
  return {Lane(name + ", left", x0, x1, 0.5 * lane, 1.5 * lane, what),
          Lane(name + ", right", x0, x1, -1.5 * lane, -0.5 * lane, what)};
}

}  // namespace

double BrakingDistanceM(double speed_m_s, double deceleration_m_s2) {
  RequirePositive(deceleration_m_s2, "a deceleration");
  if (!(speed_m_s >= 0.0)) throw Error("coverage: the speed must be >= 0");
  return speed_m_s * speed_m_s / (2.0 * deceleration_m_s2);
}

double EmergencyStopRangeM(const Scenario& s) {
  return s.speed_m_s * s.reaction_time_s +
         BrakingDistanceM(s.speed_m_s, s.aggressive_deceleration_m_s2);
}

double FollowingRangeM(const Scenario& s) {
  const double gap = s.speed_m_s * s.reaction_time_s +
                     BrakingDistanceM(s.speed_m_s, s.normal_deceleration_m_s2) -
                     BrakingDistanceM(s.speed_m_s, s.aggressive_deceleration_m_s2);
  return std::max(gap, s.speed_m_s * s.time_gap_s);
}

double OncomingRangeM(const Scenario& s) { return 2.0 * s.speed_m_s * s.overtake_time_s; }

const char* SensorTypeName(SensorType type) {
  switch (type) {
    case SensorType::kLidar:
      return "lidar";
    case SensorType::kCamera:
      return "camera";
    case SensorType::kRadar:
      return "radar";
    case SensorType::kUltrasonic:
      return "ultrasonic";
  }
  return "lidar";
}

bool Sees(const Sensor& sensor, const Body& body, const Eigen::Vector3d& target) {
  const Eigen::Vector3d d = target - sensor.position_m;
  const double range = d.norm();
  if (range > sensor.range_m || range < sensor.min_range_m) return false;
  const double horizontal = d.head<2>().norm();
  if (sensor.hfov_rad < kTwoPi) {
    const double bearing = WrapAngle(std::atan2(d.y(), d.x()) - sensor.yaw_rad);
    if (std::abs(bearing) > 0.5 * sensor.hfov_rad) return false;
  }
  const double elevation = std::atan2(d.z(), horizontal) + sensor.pitch_rad;
  if (elevation < sensor.vfov_min_rad || elevation > sensor.vfov_max_rad) return false;
  return !ThroughBody(body, sensor.position_m, target);
}

std::vector<Maneuver> Requirements(const Scenario& s, const Body& body) {
  RequirePositive(s.speed_m_s, "the speed");
  RequirePositive(s.lane_width_m, "the lane width");
  for (double v : {s.side_range_m, s.rear_range_m, s.omni_range_m, s.roundabout_range_m,
                   s.overtake_time_s, s.aggressive_deceleration_m_s2, s.normal_deceleration_m_s2}) {
    RequirePositive(v, "every range, time and deceleration");
  }
  const double half = 0.5 * s.lane_width_m;
  const double front = body.front_m, rear = body.rear_m;
  const Eigen::Vector2d centre(0.5 * (front + rear), 0.0);
  std::vector<Maneuver> out;
  for (const std::string& name : s.maneuvers) {
    Maneuver m{name, {}};
    if (name == "emergency_stop") {
      const double d = EmergencyStopRangeM(s);
      m.regions.push_back(Lane("own lane ahead", front, front + d, -half, half,
                               Metres(d) + " ahead (stopping at the aggressive rate)"));
    } else if (name == "maintain_speed") {
      const double d = FollowingRangeM(s);
      m.regions.push_back(Lane("own lane ahead", front, front + d, -half, half,
                               Metres(d) + " ahead (the lead vehicle's position and speed)"));
      for (Region& r : AdjacentLanes("adjacent lane", rear, front + s.side_range_m, s.lane_width_m,
                                     "beside and " + Metres(s.side_range_m) + " ahead")) {
        m.regions.push_back(r);
      }
    } else if (name == "lane_change") {
      for (Region& r : AdjacentLanes(
               "adjacent lane", rear - s.rear_range_m, front + s.side_range_m, s.lane_width_m,
               Metres(s.rear_range_m) + " behind to " + Metres(s.side_range_m) + " ahead")) {
        m.regions.push_back(r);
      }
      m.regions.push_back(Lane("own lane behind", rear - s.rear_range_m, rear, -half, half,
                               Metres(s.rear_range_m) + " behind"));
    } else if (name == "overtake") {
      m.regions.push_back(Lane("parked car ahead", front, front + 20.0, -3.0 * half, 3.0 * half,
                               "20 m ahead over three lanes (wide, short)"));
      const double d = OncomingRangeM(s);
      m.regions.push_back(Lane("oncoming lane", front, front + d, half, 3.0 * half,
                               Metres(d) + " ahead in the left lane (narrow, long)"));
    } else if (name == "intersection") {
      m.regions.push_back(
          {"all around", Metres(s.omni_range_m) + " around", Disc(centre, s.omni_range_m)});
    } else if (name == "roundabout") {
      m.regions.push_back({"all around", Metres(s.roundabout_range_m) + " around",
                           Disc(centre, s.roundabout_range_m)});
    } else {
      throw Error("coverage: unknown manoeuvre '" + name +
                  "' (known: emergency_stop, maintain_speed, lane_change, overtake, "
                  "intersection, roundabout)");
    }
    out.push_back(std::move(m));
  }
  return out;
}

namespace {

bool SeenByAny(const Rig& rig, const Eigen::Vector3d& target) {
  for (const Sensor& sensor : rig.sensors) {
    if (Sees(sensor, rig.body, target)) return true;
  }
  return false;
}

constexpr double kMaxMarginM = 100.0;
constexpr double kMarginStepM = 0.5;

// The least reach past a corner, over the region's corners (RegionCoverage::margin_m).
double Margin(const Rig& rig, const Scenario& s, const Region& region) {
  const Eigen::Vector2d centre(0.5 * (rig.body.front_m + rig.body.rear_m), 0.0);
  double margin = kMaxMarginM;
  for (const Eigen::Vector2d& corner : region.polygon) {
    const Eigen::Vector2d offset = corner - centre;
    if (!(offset.norm() > 0.0)) continue;
    const Eigen::Vector2d direction = offset.normalized();
    double reach = 0.0;
    while (reach < margin) {
      const Eigen::Vector2d p = corner + (reach + kMarginStepM) * direction;
      if (!SeenByAny(rig, Eigen::Vector3d(p.x(), p.y(), s.target_height_m))) break;
      reach += kMarginStepM;
    }
    if (!SeenByAny(rig, Eigen::Vector3d(corner.x(), corner.y(), s.target_height_m))) reach = 0.0;
    margin = std::min(margin, reach);
  }
  return margin;
}

RegionCoverage Analyze(const Rig& rig, const Scenario& s, const Region& region, int samples) {
  Eigen::Vector2d lo = region.polygon.front(), hi = region.polygon.front();
  for (const Eigen::Vector2d& p : region.polygon) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double step = std::sqrt((hi - lo).prod() / std::max(samples, 1));
  RegionCoverage out;
  out.region = region;
  out.sensor_fraction.assign(rig.sensors.size(), 0.0);
  int covered = 0;
  for (double x = lo.x() + 0.5 * step; x < hi.x(); x += step) {
    for (double y = lo.y() + 0.5 * step; y < hi.y(); y += step) {
      const Eigen::Vector2d p(x, y);
      if (!InsidePolygon(region.polygon, p) || InsideBody(rig.body, p)) continue;
      ++out.samples;
      const Eigen::Vector3d target(x, y, s.target_height_m);
      bool seen = false;
      for (size_t k = 0; k < rig.sensors.size(); ++k) {
        if (Sees(rig.sensors[k], rig.body, target)) {
          out.sensor_fraction[k] += 1.0;
          seen = true;
        }
      }
      if (seen) {
        ++covered;
      } else if (p.norm() > out.worst_range_m) {
        out.worst_range_m = p.norm();
        out.worst_bearing_rad = std::atan2(y, x);
      }
    }
  }
  if (out.samples > 0) {
    out.covered_fraction = static_cast<double>(covered) / out.samples;
    for (double& f : out.sensor_fraction) f /= out.samples;
  }
  out.covered = out.samples > 0 && out.covered_fraction >= s.min_covered_fraction;
  if (out.covered) out.margin_m = Margin(rig, s, region);
  return out;
}

}  // namespace

std::vector<ManeuverCoverage> AnalyzeCoverage(const Rig& rig, const Scenario& scenario,
                                              int samples_per_region) {
  std::vector<ManeuverCoverage> out;
  for (const Maneuver& m : Requirements(scenario, rig.body)) {
    ManeuverCoverage mc{m.name, {}, true};
    for (const Region& r : m.regions) {
      mc.regions.push_back(Analyze(rig, scenario, r, samples_per_region));
      mc.covered = mc.covered && mc.regions.back().covered;
    }
    out.push_back(std::move(mc));
  }
  return out;
}

std::string CoverageTable(const Rig& rig, const std::vector<ManeuverCoverage>& result) {
  std::ostringstream out;
  out << "| manoeuvre | region | requirement | covered | verdict | seen by |\n"
      << "| --- | --- | --- | --- | --- | --- |\n";
  for (const ManeuverCoverage& m : result) {
    for (const RegionCoverage& r : m.regions) {
      out << "| " << m.name << " | " << r.region.name << " | " << r.region.requirement << " | "
          << std::fixed << std::setprecision(1) << 100.0 * r.covered_fraction << " % | ";
      if (r.covered) {
        out << "covered, margin " << Metres(r.margin_m);
      } else {
        out << "short: nothing sees " << Metres(r.worst_range_m) << " at " << std::setprecision(0)
            << r.worst_bearing_rad * kRadToDeg << " deg";
      }
      out << " |";
      bool first = true;
      for (size_t k = 0; k < rig.sensors.size(); ++k) {
        if (r.sensor_fraction[k] <= 0.0) continue;
        out << (first ? " " : ", ") << rig.sensors[k].name << " " << std::setprecision(0)
            << 100.0 * r.sensor_fraction[k] << " %";
        first = false;
      }
      out << (first ? " none |\n" : " |\n");
    }
  }
  return out.str();
}

std::string CoverageSvg(const Rig& rig, const std::vector<ManeuverCoverage>& result) {
  double extent = 10.0;
  for (const ManeuverCoverage& m : result) {
    for (const RegionCoverage& r : m.regions) {
      for (const Eigen::Vector2d& p : r.region.polygon) extent = std::max(extent, p.norm());
    }
  }
  for (const Sensor& s : rig.sensors) extent = std::max(extent, std::min(s.range_m, 250.0));
  const double size = 800.0, scale = 0.5 * (size - 40.0) / extent;
  // The page's y axis points down and x right: forward is up the page, left to the left.
  const auto X = [&](const Eigen::Vector2d& p) { return 0.5 * size - scale * p.y(); };
  const auto Y = [&](const Eigen::Vector2d& p) { return 0.5 * size - scale * p.x(); };
  std::ostringstream svg;
  svg << std::fixed << std::setprecision(1) << "<svg xmlns='http://www.w3.org/2000/svg' width='"
      << size << "' height='" << size << "' viewBox='0 0 " << size << ' ' << size << "'>"
      << "<rect width='100%' height='100%' fill='white'/>";
  const char* colors[] = {"#36c", "#c63", "#393", "#939", "#399", "#993"};
  for (size_t k = 0; k < rig.sensors.size(); ++k) {
    const Sensor& s = rig.sensors[k];
    const Eigen::Vector2d o = s.position_m.head<2>();
    const double half = std::min(0.5 * s.hfov_rad, M_PI - 1e-3);
    svg << "<path fill='" << colors[k % 6] << "' fill-opacity='0.12' stroke='" << colors[k % 6]
        << "' stroke-width='0.5' d='M " << X(o) << ' ' << Y(o);
    for (int i = 0; i <= 48; ++i) {
      const double a = s.yaw_rad - half + 2.0 * half * i / 48;
      const Eigen::Vector2d p = o + s.range_m * Eigen::Vector2d(std::cos(a), std::sin(a));
      svg << " L " << X(p) << ' ' << Y(p);
    }
    svg << " Z'><title>" << EscapeXml(s.name) << "</title></path>";
  }
  for (const ManeuverCoverage& m : result) {
    for (const RegionCoverage& r : m.regions) {
      svg << "<polygon fill='none' stroke='" << (r.covered ? "#2a2" : "#d22")
          << "' stroke-width='1.2' points='";
      for (const Eigen::Vector2d& p : r.region.polygon) svg << X(p) << ',' << Y(p) << ' ';
      svg << "'><title>" << EscapeXml(m.name + ": " + r.region.name) << "</title></polygon>";
    }
  }
  const Body& b = rig.body;
  const Eigen::Vector2d front_left(b.front_m, b.half_width_m);
  svg << "<rect x='" << X(front_left) << "' y='" << Y(front_left) << "' width='"
      << 2.0 * b.half_width_m * scale << "' height='" << (b.front_m - b.rear_m) * scale
      << "' fill='#333'/><text x='10' y='20' font-family='sans-serif' font-size='13'>"
      << EscapeXml(rig.name)
      << ": sensor wedges over the required regions (green covered, red short); "
      << "forward is up</text></svg>\n";
  return svg.str();
}

}  // namespace coverage
}  // namespace autocal
