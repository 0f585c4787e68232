#pragma once

// The simulated drive: a planar path given as heading over arc length, a speed profile over
// time, the ground height field and a small body-dynamics model. Together they define the
// vehicle pose T_W_V(t) as a closed-form function of time (up to a high-order quadrature
// of the heading for x, y), which is differentiated exactly — not by finite differences —
// to produce velocity, acceleration and body rate for the IMU (docs/simulator.md).

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <memory>
#include <vector>

#include "autocal/common/units.h"
#include "autocal/geometry/se3.h"
#include "autocal/sim/ground.h"
#include "autocal/sim/smooth_step.h"

namespace autocal {
namespace sim {

// Speed over time, starting at t = 0 and s = 0: pieces that hold the speed or change it with
// a smooth step. Outside the pieces the speed stays constant.
class SpeedProfile {
 public:
  explicit SpeedProfile(double initial_speed_m_s = 0.0);

  // Keeps the current speed for duration_s (> 0).
  void Hold(double duration_s);
  // Reaches target_m_s (>= 0) after duration_s (> 0); the peak acceleration is
  // kSmoothStepPeakSlope * |target - current| / duration_s.
  void ChangeSpeed(double target_m_s, double duration_s);

  double end_time_s() const;
  double end_distance_m() const;
  double final_speed_m_s() const;

  // Distance s(t), speed v(t) = ds/dt and acceleration a(t) = dv/dt.
  template <typename T>
  void Evaluate(const T& t, T* s, T* v, T* a) const {
    const double t0 = ScalarValue(t);
    const Piece* piece = nullptr;
    if (!pieces_.empty() && t0 >= pieces_.front().t0) {
      size_t lo = 0, hi = pieces_.size();
      while (hi - lo > 1) {
        const size_t mid = (lo + hi) / 2;
        (pieces_[mid].t0 <= t0 ? lo : hi) = mid;
      }
      piece = &pieces_[lo];
      if (t0 > piece->t0 + piece->duration) piece = nullptr;
    }
    if (piece == nullptr) {
      // Constant speed before the first piece (initial speed) or after the last one.
      const bool before = pieces_.empty() || t0 < 0.0;
      const double v_const = before ? initial_speed_m_s_ : final_speed_m_s();
      const double t_ref = before ? 0.0 : end_time_s();
      const double s_ref = before ? 0.0 : end_distance_m();
      *s = T(s_ref) + T(v_const) * (t - T(t_ref));
      *v = T(v_const);
      *a = T(0.0);
      return;
    }
    const T dt = t - T(piece->t0);
    const T x = dt / T(piece->duration);
    const double dv = piece->v1 - piece->v0;
    *s = T(piece->s0) + T(piece->v0) * dt + T(dv * piece->duration) * SmoothStepIntegral(x);
    *v = T(piece->v0) + T(dv) * SmoothStep(x);
    *a = T(dv / piece->duration) * SmoothStepDerivative(x);
  }

 private:
  struct Piece {
    double t0 = 0.0;
    double duration = 0.0;
    double s0 = 0.0;
    double v0 = 0.0;
    double v1 = 0.0;
  };
  double initial_speed_m_s_;
  std::vector<Piece> pieces_;
};

// A planar path: heading psi(s) over arc length s as polynomial pieces, x, y by quadrature of
// (cos psi, sin psi). Curvature is continuous with two continuous derivatives everywhere,
// except at pivots: a pivot (a turn on the spot) makes the direction of travel jump at one
// arc length; the body turns there in time, while standing (PivotProfile). Before s = 0 and
// after the end the path continues straight.
class PathProfile {
 public:
  PathProfile(const Eigen::Vector2d& start_xy, double start_heading_rad);

  void AddStraight(double length_m);
  // A turn by heading_change_rad (left positive) on a circle of radius_m entered and left
  // through curvature ramps of ramp_length_m (smooth-step clothoids). Throws autocal::Error
  // if the ramps alone turn more than heading_change_rad.
  void AddArc(double heading_change_rad, double radius_m, double ramp_length_m);
  // A lateral shift of about lateral_shift_m (left positive) over length_m, heading back to
  // where it started: psi = h x^5 (1-x)^5 with h = 2772 shift / length.
  void AddLaneChange(double lateral_shift_m, double length_m);
  // A turn on the spot by heading_change_rad (left positive) at the current end: the pieces
  // added afterwards start in the new direction.
  void AddPivot(double heading_change_rad);

  double length_m() const { return length_m_; }
  double final_heading_rad() const;

  // Sum of the pivots before arc length s (as Heading(s) sees them): Heading(s) minus this
  // is continuous across pivots.
  double PivotsBefore(double s) const {
    const Piece* piece = Find(s);
    if (piece == nullptr) return s < 0.0 ? 0.0 : pivot_total_;
    return piece->pivots;
  }

  template <typename T>
  T Heading(const T& s) const {
    const Piece* piece = Find(ScalarValue(s));
    if (piece == nullptr) return T(ScalarValue(s) < 0.0 ? start_heading_ : final_heading_rad());
    const T x = (s - T(piece->s0)) / T(piece->length);
    T poly = T(piece->coeffs.back());
    for (int k = kDegree - 1; k >= 0; --k) poly = poly * x + T(piece->coeffs[k]);
    return T(piece->psi0) + poly;
  }

  template <typename T>
  T Curvature(const T& s) const {
    const Piece* piece = Find(ScalarValue(s));
    if (piece == nullptr) return T(0.0);
    const T x = (s - T(piece->s0)) / T(piece->length);
    T poly = T(kDegree * piece->coeffs[kDegree]);
    for (int k = kDegree - 1; k >= 1; --k) poly = poly * x + T(k * piece->coeffs[k]);
    return poly / T(piece->length);
  }

  // (x, y) at arc length s (8-point Gauss-Legendre from the nearest tabulated point, at most
  // 2 m away: exact to rounding for these smooth headings).
  Eigen::Vector2d Position(double s) const;

 private:
  static constexpr int kDegree = 10;
  struct Piece {
    double s0 = 0.0;
    double length = 1.0;
    double psi0 = 0.0;
    std::array<double, kDegree + 1> coeffs{};  // psi - psi0 in powers of (s - s0) / length
    double pivots = 0.0;                       // sum of the pivots before this piece
  };
  struct Node {
    double s = 0.0;
    Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  };
  void AddPiece(double length, const std::array<double, kDegree + 1>& coeffs);
  const Piece* Find(double s) const;
  Eigen::Vector2d Integrate(double s_from, double s_to) const;

  Eigen::Vector2d start_xy_;
  double start_heading_;
  double length_m_ = 0.0;
  double pivot_total_ = 0.0;  // sum of every pivot so far
  std::vector<Piece> pieces_;
  std::vector<Node> nodes_;  // tabulated positions, at most 2 m apart
};

// Turns on the spot over time: each pivot changes the body's yaw by a smooth step while the
// vehicle stands (a skid-steer platform turning in place). Yaw(t) is the sum of the pivots
// done by t; between pivots it is constant.
class PivotProfile {
 public:
  // A pivot of heading_change_rad starting at t0_s and lasting duration_s (> 0); pivots are
  // added in time order and must not overlap.
  void Add(double t0_s, double duration_s, double heading_change_rad);
  bool empty() const { return pivots_.empty(); }

  template <typename T>
  T Yaw(const T& t) const {
    const double t0 = ScalarValue(t);
    T yaw = T(0.0);
    for (const Pivot& p : pivots_) {
      if (t0 >= p.t0 + p.duration) {
        yaw = yaw + T(p.change);
      } else if (t0 > p.t0) {
        yaw = yaw + T(p.change) * SmoothStep((t - T(p.t0)) / T(p.duration));
      }
    }
    return yaw;
  }

 private:
  struct Pivot {
    double t0 = 0.0;
    double duration = 0.0;
    double change = 0.0;
  };
  std::vector<Pivot> pivots_;
};

// How the body moves on its suspension, and where the rear axle sits.
struct VehicleDynamicsOptions {
  // Body roll per lateral acceleration (rolls out of the turn), rad per m/s^2 (0.4 deg).
  double roll_per_lateral_accel = 0.4 * kDegToRad;
  // Body pitch per longitudinal acceleration (nose up when accelerating), rad per m/s^2.
  double pitch_per_longitudinal_accel = 0.3 * kDegToRad;
  // Slip angle of the rear axle per lateral acceleration, rad per m/s^2 (its cornering
  // compliance; 0: the rear wheels roll without slipping sideways). In a turn the rear axle
  // slides outwards: the body yaws into the turn by this times v^2 kappa from the direction
  // the axle travels, so V's origin moves sideways in V at -v sin(slip).
  double rear_slip_per_lateral_accel = 0.0;
  // Height of the rear-axle centre (V origin) above the road along the road normal, m.
  double rear_axle_height_m = 0.33;
};

// Kinematics of a frame B rigidly attached to the vehicle, at one instant (exact derivatives).
struct BodyState {
  geometry::Pose3d T_W_B;
  Eigen::Vector3d v_W = Eigen::Vector3d::Zero();      // velocity of B's origin, in W
  Eigen::Vector3d a_W = Eigen::Vector3d::Zero();      // acceleration of B's origin, in W
  Eigen::Vector3d omega_B = Eigen::Vector3d::Zero();  // angular velocity of B w.r.t. W, in B
};

class VehicleTrajectory {
 public:
  // The pivots must happen while the speed profile stands, at the arc lengths of the path's
  // pivots (DriveBuilder in scenario.cc plans both together).
  VehicleTrajectory(PathProfile path, SpeedProfile speed,
                    std::shared_ptr<const GroundSurface> ground,
                    VehicleDynamicsOptions dynamics = {}, PivotProfile pivots = {});

  // T_W_V at time t_s (seconds from the start of the drive).
  geometry::Pose3d PoseAt(double t_s) const;
  // Pose, velocity, acceleration and body rate of the frame B with T_V_B (default: V).
  BodyState StateAt(double t_s, const geometry::Pose3d& T_V_B = geometry::Pose3d()) const;

  double ArcLengthAt(double t_s) const;
  // A point on the ground at path arc length s, lateral_m to the left of the path.
  Eigen::Vector3d GroundPointBeside(double s, double lateral_m) const;

  const PathProfile& path() const { return path_; }
  const SpeedProfile& speed() const { return speed_; }
  const GroundSurface& ground() const { return *ground_; }
  const VehicleDynamicsOptions& dynamics() const { return dynamics_; }
  const PivotProfile& pivots() const { return pivots_; }

 private:
  template <typename T>
  void Evaluate(const T& t, Eigen::Matrix<T, 3, 3>* R_W_V, Eigen::Matrix<T, 3, 1>* p_W_V) const;

  PathProfile path_;
  SpeedProfile speed_;
  std::shared_ptr<const GroundSurface> ground_;
  VehicleDynamicsOptions dynamics_;
  PivotProfile pivots_;
};

}  // namespace sim
}  // namespace autocal
