#include "autocal/sim/trajectory.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "sim/taylor.h"

namespace autocal {
namespace sim {
namespace {

// 8-point Gauss-Legendre rule on [-1, 1] (exact for polynomials of degree 15).
constexpr std::array<double, 8> kGaussNodes = {
    -0.9602898564975363, -0.7966664774136267, -0.5255324099163290, -0.1834346424956498,
    0.1834346424956498,  0.5255324099163290,  0.7966664774136267,  0.9602898564975363};
constexpr std::array<double, 8> kGaussWeights = {
    0.1012285362903763, 0.2223810344533745, 0.3137066458778873, 0.3626837833783620,
    0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763};

constexpr double kMaxNodeSpacingM = 2.0;

void CheckPositive(double value, const char* what) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw Error(std::string("simulated trajectory: ") + what +
                " must be positive and finite, got " + std::to_string(value));
  }
}

}  // namespace

// ----- SpeedProfile -------------------------------------------------------------------------

SpeedProfile::SpeedProfile(double initial_speed_m_s) : initial_speed_m_s_(initial_speed_m_s) {
  if (!(initial_speed_m_s >= 0.0)) throw Error("simulated speed profile: negative initial speed");
}

double SpeedProfile::end_time_s() const {
  return pieces_.empty() ? 0.0 : pieces_.back().t0 + pieces_.back().duration;
}

double SpeedProfile::end_distance_m() const {
  if (pieces_.empty()) return 0.0;
  const Piece& p = pieces_.back();
  return p.s0 + 0.5 * (p.v0 + p.v1) * p.duration;  // the smooth step integrates to 1/2
}

double SpeedProfile::final_speed_m_s() const {
  return pieces_.empty() ? initial_speed_m_s_ : pieces_.back().v1;
}

void SpeedProfile::Hold(double duration_s) { ChangeSpeed(final_speed_m_s(), duration_s); }

void SpeedProfile::ChangeSpeed(double target_m_s, double duration_s) {
  CheckPositive(duration_s, "speed-change duration");
  if (!(target_m_s >= 0.0)) throw Error("simulated speed profile: negative target speed");
  Piece piece;
  piece.t0 = end_time_s();
  piece.duration = duration_s;
  piece.s0 = end_distance_m();
  piece.v0 = final_speed_m_s();
  piece.v1 = target_m_s;
  pieces_.push_back(piece);
}

// ----- PathProfile --------------------------------------------------------------------------

PathProfile::PathProfile(const Eigen::Vector2d& start_xy, double start_heading_rad)
    : start_xy_(start_xy), start_heading_(start_heading_rad) {
  nodes_.push_back({0.0, start_xy});
}

double PathProfile::final_heading_rad() const {
  if (pieces_.empty()) return pivot_total_ == 0.0 ? start_heading_ : start_heading_ + pivot_total_;
  const Piece& p = pieces_.back();
  double sum = 0.0;
  for (double c : p.coeffs) sum += c;
  const double heading = p.psi0 + sum;
  // Pivots after the last piece (none in a drive without pivots: the sum stays untouched).
  return pivot_total_ == p.pivots ? heading : heading + (pivot_total_ - p.pivots);
}

void PathProfile::AddPivot(double heading_change_rad) {
  if (!std::isfinite(heading_change_rad)) throw Error("simulated path: pivot angle not finite");
  pivot_total_ += heading_change_rad;
}

const PathProfile::Piece* PathProfile::Find(double s) const {
  if (pieces_.empty() || s < 0.0 || s > length_m_) return nullptr;
  size_t lo = 0, hi = pieces_.size();
  while (hi - lo > 1) {
    const size_t mid = (lo + hi) / 2;
    (pieces_[mid].s0 <= s ? lo : hi) = mid;
  }
  return &pieces_[lo];
}

void PathProfile::AddPiece(double length, const std::array<double, kDegree + 1>& coeffs) {
  CheckPositive(length, "path piece length");
  Piece piece;
  piece.s0 = length_m_;
  piece.length = length;
  piece.psi0 = final_heading_rad();
  piece.coeffs = coeffs;
  piece.pivots = pivot_total_;
  pieces_.push_back(piece);
  // Tabulate positions along the new piece; the quadrature below reads the heading of this
  // piece, so length_m_ must already cover it.
  const double s_begin = length_m_;
  length_m_ += length;
  const int steps = std::max(1, static_cast<int>(std::ceil(length / kMaxNodeSpacingM)));
  for (int i = 1; i <= steps; ++i) {
    const double s = s_begin + length * i / steps;
    const Node& last = nodes_.back();
    nodes_.push_back({s, last.xy + Integrate(last.s, s)});
  }
}

void PathProfile::AddStraight(double length_m) { AddPiece(length_m, {}); }

void PathProfile::AddArc(double heading_change_rad, double radius_m, double ramp_length_m) {
  CheckPositive(radius_m, "arc radius");
  CheckPositive(ramp_length_m, "arc ramp length");
  const double sign = heading_change_rad >= 0.0 ? 1.0 : -1.0;
  const double kappa = sign / radius_m;
  // Each ramp turns kappa * ramp / 2; the circle turns the rest.
  const double arc_length = std::abs(heading_change_rad) * radius_m - ramp_length_m;
  if (arc_length < 0.0) {
    throw Error("simulated path: ramps of " + std::to_string(ramp_length_m) +
                " m turn more than the requested " + std::to_string(heading_change_rad) +
                " rad at radius " + std::to_string(radius_m) + " m");
  }
  // Ramp in: kappa(x) = kappa S(x), psi = kappa L (7x^5 - 14x^6 + 10x^7 - 2.5x^8).
  const double k_ramp = kappa * ramp_length_m;
  AddPiece(ramp_length_m,
           {0, 0, 0, 0, 0, 7 * k_ramp, -14 * k_ramp, 10 * k_ramp, -2.5 * k_ramp, 0, 0});
  if (arc_length > 1e-9) AddPiece(arc_length, {0, kappa * arc_length, 0, 0, 0, 0, 0, 0, 0, 0, 0});
  // Ramp out: kappa(x) = kappa (1 - S(x)), psi = kappa L (x - integral of S).
  AddPiece(ramp_length_m,
           {0, k_ramp, 0, 0, 0, -7 * k_ramp, 14 * k_ramp, -10 * k_ramp, 2.5 * k_ramp, 0, 0});
}

void PathProfile::AddLaneChange(double lateral_shift_m, double length_m) {
  CheckPositive(length_m, "lane-change length");
  // psi = h x^5 (1 - x)^5: curvature ~ x^4 at the ends, so curvature and its first three
  // derivatives are continuous (body roll follows curvature; the IMU jerk stays continuous).
  // The shift is about the integral of psi (small angles): h L B(6, 6) = h L / 2772.
  const double h = 2772.0 * lateral_shift_m / length_m;
  AddPiece(length_m, {0, 0, 0, 0, 0, h, -5 * h, 10 * h, -10 * h, 5 * h, -h});
}

Eigen::Vector2d PathProfile::Integrate(double s_from, double s_to) const {
  const double half = 0.5 * (s_to - s_from);
  const double mid = 0.5 * (s_to + s_from);
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < kGaussNodes.size(); ++i) {
    const double psi = Heading(mid + half * kGaussNodes[i]);
    sum += kGaussWeights[i] * Eigen::Vector2d(std::cos(psi), std::sin(psi));
  }
  return half * sum;
}

Eigen::Vector2d PathProfile::Position(double s) const {
  if (s <= 0.0) {
    return start_xy_ + s * Eigen::Vector2d(std::cos(start_heading_), std::sin(start_heading_));
  }
  if (s >= length_m_) {
    const double psi = final_heading_rad();
    return nodes_.back().xy + (s - length_m_) * Eigen::Vector2d(std::cos(psi), std::sin(psi));
  }
  const auto it = std::upper_bound(nodes_.begin(), nodes_.end(), s,
                                   [](double value, const Node& n) { return value < n.s; });
  const Node& node = *(it - 1);
  return node.xy + Integrate(node.s, s);
}

// ----- PivotProfile -------------------------------------------------------------------------

void PivotProfile::Add(double t0_s, double duration_s, double heading_change_rad) {
  CheckPositive(duration_s, "pivot duration");
  if (!std::isfinite(t0_s) || !std::isfinite(heading_change_rad)) {
    throw Error("simulated pivot: start and angle must be finite");
  }
  if (!pivots_.empty() && t0_s < pivots_.back().t0 + pivots_.back().duration) {
    throw Error("simulated pivot: pivots must be in time order without overlap");
  }
  pivots_.push_back({t0_s, duration_s, heading_change_rad});
}

// ----- VehicleTrajectory --------------------------------------------------------------------

namespace {

// Planar position for a plain or a derivative-carrying arc length: d(x, y)/ds is
// (cos psi, sin psi), so the time derivatives follow from the chain rule without quadrature.
Eigen::Vector2d PlanarPosition(const PathProfile& path, double s) { return path.Position(s); }

Eigen::Matrix<Taylor2, 2, 1> PlanarPosition(const PathProfile& path, const Taylor2& s) {
  const Eigen::Vector2d xy = path.Position(s.v);
  const Taylor2 psi = path.Heading(s);
  const Taylor2 c = cos(psi), sn = sin(psi);
  // d/dt x = cos(psi) s', d2/dt2 x = (d/dt cos(psi)) s' + cos(psi) s''.
  return Eigen::Matrix<Taylor2, 2, 1>(Taylor2(xy.x(), c.v * s.d1, c.d1 * s.d1 + c.v * s.d2),
                                      Taylor2(xy.y(), sn.v * s.d1, sn.d1 * s.d1 + sn.v * s.d2));
}

template <typename T>
Eigen::Matrix<T, 3, 3> RotY(const T& angle) {
  using std::cos;
  using std::sin;
  const T c = cos(angle), s = sin(angle);
  Eigen::Matrix<T, 3, 3> R;
  R << c, T(0.0), s, T(0.0), T(1.0), T(0.0), -s, T(0.0), c;
  return R;
}

template <typename T>
Eigen::Matrix<T, 3, 3> RotX(const T& angle) {
  using std::cos;
  using std::sin;
  const T c = cos(angle), s = sin(angle);
  Eigen::Matrix<T, 3, 3> R;
  R << T(1.0), T(0.0), T(0.0), T(0.0), c, -s, T(0.0), s, c;
  return R;
}

}  // namespace

VehicleTrajectory::VehicleTrajectory(PathProfile path, SpeedProfile speed,
                                     std::shared_ptr<const GroundSurface> ground,
                                     VehicleDynamicsOptions dynamics, PivotProfile pivots)
    : path_(std::move(path)),
      speed_(std::move(speed)),
      ground_(std::move(ground)),
      dynamics_(dynamics),
      pivots_(std::move(pivots)) {
  if (!ground_) throw Error("simulated trajectory: no ground surface");
}

template <typename T>
void VehicleTrajectory::Evaluate(const T& t, Eigen::Matrix<T, 3, 3>* R_W_V,
                                 Eigen::Matrix<T, 3, 1>* p_W_V) const {
  using std::cos;
  using std::sin;
  using std::sqrt;
  using Vec3 = Eigen::Matrix<T, 3, 1>;
  T s, v, a;
  speed_.Evaluate(t, &s, &v, &a);
  // Body yaw: the path heading, with the path's pivots replaced by the turns on the spot done
  // by time t (equal to them whenever the vehicle moves). The direction of travel inside
  // PlanarPosition stays the path heading.
  T psi = path_.Heading(s);
  if (!pivots_.empty()) psi = psi - T(path_.PivotsBefore(ScalarValue(s))) + pivots_.Yaw(t);
  const T kappa = path_.Curvature(s);
  // The rear axle's slip: the body yaws into the turn from the direction of travel.
  psi = psi + T(dynamics_.rear_slip_per_lateral_accel) * v * v * kappa;
  const Eigen::Matrix<T, 2, 1> xy = PlanarPosition(path_, s);
  const T z = ground_->Height(xy(0), xy(1));
  const Eigen::Matrix<T, 2, 1> grad = ground_->Gradient(xy(0), xy(1));

  // Road frame: z along the ground normal, x along the heading projected onto the ground.
  Vec3 n(-grad(0), -grad(1), T(1.0));
  n /= sqrt(n.dot(n));
  const Vec3 h(cos(psi), sin(psi), T(0.0));
  Vec3 x_axis = h - h.dot(n) * n;
  x_axis /= sqrt(x_axis.dot(x_axis));
  const Vec3 y_axis = n.cross(x_axis);
  Eigen::Matrix<T, 3, 3> R_road;
  R_road.col(0) = x_axis;
  R_road.col(1) = y_axis;
  R_road.col(2) = n;

  // Body on its suspension: rolls out of a turn (lateral acceleration v^2 kappa to the left
  // gives positive roll, left side up) and pitches nose up when accelerating (negative
  // rotation about y, which points left).
  const T roll = T(dynamics_.roll_per_lateral_accel) * v * v * kappa;
  const T pitch = -T(dynamics_.pitch_per_longitudinal_accel) * a;
  *R_W_V = R_road * RotY(pitch) * RotX(roll);
  *p_W_V = Vec3(xy(0), xy(1), z) + T(dynamics_.rear_axle_height_m) * n;
}

geometry::Pose3d VehicleTrajectory::PoseAt(double t_s) const {
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  Evaluate(t_s, &R, &p);
  return geometry::Pose3d(Eigen::Quaterniond(R).normalized(), p);
}

BodyState VehicleTrajectory::StateAt(double t_s, const geometry::Pose3d& T_V_B) const {
  Eigen::Matrix<Taylor2, 3, 3> R_W_V;
  Eigen::Matrix<Taylor2, 3, 1> p_W_V;
  Evaluate(Taylor2::Variable(t_s), &R_W_V, &p_W_V);
  const Eigen::Matrix<Taylor2, 3, 3> R_W_B = R_W_V * T_V_B.R().cast<Taylor2>();
  const Eigen::Matrix<Taylor2, 3, 1> p_W_B = p_W_V + R_W_V * T_V_B.p.cast<Taylor2>();
  Eigen::Matrix3d R, R_dot;
  for (int i = 0; i < 9; ++i) {
    R(i) = R_W_B(i).v;
    R_dot(i) = R_W_B(i).d1;
  }
  BodyState state;
  state.T_W_B = geometry::Pose3d(Eigen::Quaterniond(R).normalized(), Eigen::Vector3d::Zero());
  for (int i = 0; i < 3; ++i) {
    state.T_W_B.p(i) = p_W_B(i).v;
    state.v_W(i) = p_W_B(i).d1;
    state.a_W(i) = p_W_B(i).d2;
  }
  // dR/dt = R Hat(omega_B).
  state.omega_B = geometry::Vee(R.transpose() * R_dot);
  return state;
}

double VehicleTrajectory::ArcLengthAt(double t_s) const {
  double s, v, a;
  speed_.Evaluate(t_s, &s, &v, &a);
  return s;
}

Eigen::Vector3d VehicleTrajectory::GroundPointBeside(double s, double lateral_m) const {
  const double psi = path_.Heading(s);
  const Eigen::Vector2d xy =
      path_.Position(s) + lateral_m * Eigen::Vector2d(-std::sin(psi), std::cos(psi));
  return Eigen::Vector3d(xy.x(), xy.y(), ground_->Height(xy.x(), xy.y()));
}

}  // namespace sim
}  // namespace autocal
