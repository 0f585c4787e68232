#include "autocal/estimation/imu_motion_table.h"

#include <algorithm>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/geometry/quaternion_plus.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace estimation {

namespace {

// Linear interpolation of a sample at t_ns between its neighbours.
sensors::ImuSample Interpolate(const sensors::ImuSample& a, const sensors::ImuSample& b,
                               int64_t t_ns) {
  const double s = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  sensors::ImuSample out;
  out.t_ns = t_ns;
  out.gyro_rad_s = (1.0 - s) * a.gyro_rad_s + s * b.gyro_rad_s;
  out.accel_m_s2 = (1.0 - s) * a.accel_m_s2 + s * b.accel_m_s2;
  return out;
}

// The knots of the piecewise-linear IMU signal over [from, to] (inside the samples): the ends
// interpolated, the samples between.
std::vector<sensors::ImuSample> KnotsOver(const sensors::ImuSamples& imu, int64_t from,
                                          int64_t to) {
  auto first = std::upper_bound(imu.begin(), imu.end(), from,
                                [](int64_t t, const sensors::ImuSample& s) { return t < s.t_ns; });
  if (first == imu.end()) --first;  // `from` is the last sample
  std::vector<sensors::ImuSample> knots;
  knots.push_back(Interpolate(*(first - 1), *first, from));
  for (auto it = first; it != imu.end() && it->t_ns < to; ++it) knots.push_back(*it);
  if (knots.back().t_ns < to) {
    auto last = std::lower_bound(imu.begin(), imu.end(), to,
                                 [](const sensors::ImuSample& s, int64_t t) { return s.t_ns < t; });
    knots.push_back(last->t_ns == to ? *last : Interpolate(*(last - 1), *last, to));
  }
  return knots;
}

}  // namespace

bool ImuMotionTable::Covers(const sensors::ImuSamples& imu, int64_t t_begin_ns, int64_t t_end_ns) {
  return imu.size() >= 2 && t_begin_ns >= imu.front().t_ns && t_end_ns <= imu.back().t_ns &&
         t_end_ns >= t_begin_ns;
}

ImuMotionTable::ImuMotionTable(const sensors::ImuSamples& imu, int64_t t_begin_ns, int64_t t_end_ns,
                               const Eigen::Vector3d& b_g, const Eigen::Vector3d& b_a,
                               int64_t rate_window_ns, std::optional<int64_t> t_origin_ns)
    : t_origin_ns_(t_origin_ns.value_or(t_begin_ns)),
      t_begin_ns_(t_begin_ns),
      t_end_ns_(t_end_ns),
      rate_window_ns_(rate_window_ns) {
  if (!Covers(imu, t_begin_ns, t_end_ns)) {
    throw Error("ImuMotionTable: the IMU samples do not cover [" + std::to_string(t_begin_ns) +
                ", " + std::to_string(t_end_ns) + "] ns");
  }
  if (t_origin_ns_ < t_begin_ns || t_origin_ns_ > t_end_ns) {
    throw Error("ImuMotionTable: the origin " + std::to_string(t_origin_ns_) +
                " ns lies outside the tabulated [" + std::to_string(t_begin_ns) + ", " +
                std::to_string(t_end_ns) + "] ns");
  }
  // The IMU signal is piecewise linear between samples: the boundaries are interpolated and
  // each step integrates the mean of its end values.
  std::vector<sensors::ImuSample> knots = KnotsOver(imu, t_begin_ns, t_end_ns);
  // The origin is a knot too, so that the steps from it are those of a table that starts there.
  auto after = std::upper_bound(knots.begin(), knots.end(), t_origin_ns_,
                                [](int64_t t, const sensors::ImuSample& k) { return t < k.t_ns; });
  if (after != knots.begin() && after != knots.end() && (after - 1)->t_ns < t_origin_ns_) {
    knots.insert(after, Interpolate(*(after - 1), *after, t_origin_ns_));
  }

  Node node{t_begin_ns,
            Eigen::Quaterniond::Identity(),
            Eigen::Vector3d::Zero(),
            Eigen::Vector3d::Zero(),
            Eigen::Vector3d::Zero(),
            Eigen::Vector3d::Zero(),
            Eigen::Vector3d::Zero(),
            Eigen::Vector3d::Zero()};
  for (size_t i = 0; i + 1 < knots.size(); ++i) {
    const double dt = SecondsBetween(knots[i].t_ns, knots[i + 1].t_ns);
    node.t_ns = knots[i].t_ns;
    node.gyro = knots[i].gyro_rad_s - b_g;
    node.accel = knots[i].accel_m_s2 - b_a;
    node.gyro_slope = (knots[i + 1].gyro_rad_s - knots[i].gyro_rad_s) / dt;
    node.accel_slope = (knots[i + 1].accel_m_s2 - knots[i].accel_m_s2) / dt;
    nodes_.push_back(node);
    Step(dt, &node);
  }
  node.t_ns = knots.back().t_ns;
  node.gyro = knots.back().gyro_rad_s - b_g;
  node.accel = knots.back().accel_m_s2 - b_a;
  node.gyro_slope.setZero();
  node.accel_slope.setZero();
  nodes_.push_back(node);  // terminal node
  if (t_origin_ns_ > t_begin_ns) Rebase();

  if (rate_window_ns_ <= 0) return;
  // Eq. P1b's signal: half a window beyond the table on each side, as far as the samples go.
  const int64_t from = std::max(imu.front().t_ns, t_begin_ns - rate_window_ns_ / 2);
  const int64_t to = std::min(imu.back().t_ns, t_end_ns + rate_window_ns_ / 2);
  for (const sensors::ImuSample& sample : KnotsOver(imu, from, to)) {
    RateKnot knot{sample.t_ns, sample.gyro_rad_s - b_g, Eigen::Vector3d::Zero()};
    if (!rate_knots_.empty()) {
      const RateKnot& last = rate_knots_.back();
      knot.integral =
          last.integral + 0.5 * SecondsBetween(last.t_ns, knot.t_ns) * (last.gyro + knot.gyro);
    }
    rate_knots_.push_back(knot);
  }
}

// The motion `dt` seconds past node n's start, in n's deltas (the rest of n stays): the step's
// mean rate and specific force over [0, dt] (a linear signal's mean is that of its ends), the
// force rotated with the attitude at the middle of the interval (midpoint rule).
void ImuMotionTable::Step(double dt, Node* n) {
  const Eigen::Vector3d gyro = n->gyro + 0.5 * dt * n->gyro_slope;
  const Eigen::Vector3d accel = n->accel + 0.5 * dt * n->accel_slope;
  const Eigen::Vector3d a_k =
      n->delta_q * (geometry::Exp(Eigen::Vector3d(0.5 * dt * gyro)) * accel);
  n->delta_p += n->delta_v * dt + 0.5 * a_k * dt * dt;
  n->delta_v += a_k * dt;
  n->delta_q = geometry::QuaternionPlus(n->delta_q, Eigen::Vector3d(gyro * dt));
}

// The deltas from the origin o instead of the table's start a (Forster's definitions):
// dR_o(t) = dR_a(o)^T dR_a(t), dv_o(t) = dR_a(o)^T (dv_a(t) - dv_a(o)) and
// dp_o(t) = dR_a(o)^T (dp_a(t) - dp_a(o) - dv_a(o) (t - o)); gravity's terms cancel. Step()
// is linear in a node's deltas, so a partial step from a rebased node is the rebased step.
void ImuMotionTable::Rebase() {
  const Node o = NodeAt(t_origin_ns_);
  const Eigen::Quaterniond q_inv = o.delta_q.conjugate();
  for (Node& n : nodes_) {
    const double dt = SecondsBetween(t_origin_ns_, n.t_ns);
    n.delta_p = q_inv * (n.delta_p - o.delta_p - dt * o.delta_v);
    n.delta_v = q_inv * (n.delta_v - o.delta_v);
    n.delta_q = (q_inv * n.delta_q).normalized();
  }
}

ImuMotionTable::Node ImuMotionTable::NodeAt(int64_t t_ns) const {
  auto it = std::upper_bound(nodes_.begin(), nodes_.end(), t_ns,
                             [](int64_t t, const Node& n) { return t < n.t_ns; });
  Node n = *(it - 1);
  Step(SecondsBetween(n.t_ns, t_ns), &n);
  return n;
}

factors::PointMotion ImuMotionTable::At(int64_t t_ns) const {
  t_ns = std::clamp(t_ns, t_begin_ns_, t_end_ns_);
  const Node n = NodeAt(t_ns);
  factors::PointMotion m;
  m.dt_s = SecondsBetween(t_origin_ns_, t_ns);
  m.delta_q = n.delta_q;
  m.delta_v = n.delta_v;
  m.delta_p = n.delta_p;
  // Step() advances the deltas only: n.t_ns and n.gyro are still the step's start.
  m.omega_rad_s = MeanRate(t_ns, n.gyro + SecondsBetween(n.t_ns, t_ns) * n.gyro_slope);
  return m;
}

Eigen::Vector3d ImuMotionTable::GyroIntegral(int64_t t_ns) const {
  auto it = std::upper_bound(rate_knots_.begin(), rate_knots_.end(), t_ns,
                             [](int64_t t, const RateKnot& k) { return t < k.t_ns; });
  if (it == rate_knots_.end()) --it;  // t_ns is the last knot
  const RateKnot& a = *(it - 1);
  const RateKnot& b = *it;
  const double h = SecondsBetween(a.t_ns, t_ns);
  const Eigen::Vector3d slope = (b.gyro - a.gyro) / SecondsBetween(a.t_ns, b.t_ns);
  return a.integral + h * (a.gyro + 0.5 * h * slope);
}

Eigen::Vector3d ImuMotionTable::MeanRate(int64_t t_ns, const Eigen::Vector3d& at_t) const {
  if (rate_knots_.size() < 2) return at_t;
  const int64_t half = std::min(
      {rate_window_ns_ / 2, t_ns - rate_knots_.front().t_ns, rate_knots_.back().t_ns - t_ns});
  if (half <= 0) return at_t;
  return (GyroIntegral(t_ns + half) - GyroIntegral(t_ns - half)) / NsToSeconds(2 * half);
}

SweepSpan SpanOf(const lidar::LidarSweep& sweep) {
  const lidar::PointCloud& cloud = sweep.cloud;
  if (!cloud.has_time()) return {};
  return {cloud.time_s.minCoeff(), cloud.time_s.maxCoeff()};
}

int64_t KeyframeTime(int64_t t_sweep_ns, const SweepSpan& span, double offset_s) {
  return t_sweep_ns + SecondsToNs(offset_s + 0.5 * (span.first_s + span.last_s));
}

int64_t KeyframeTime(const lidar::LidarSweep& sweep, double offset_s) {
  return KeyframeTime(sweep.t_ns, SpanOf(sweep), offset_s);
}

ImuInterval SweepImuInterval(int64_t t_sweep_ns, const SweepSpan& span, double offset_s) {
  return {t_sweep_ns + SecondsToNs(std::min(0.0, span.first_s) + offset_s),
          t_sweep_ns + SecondsToNs(std::max(0.0, span.last_s) + offset_s)};
}

ImuInterval MotionTableInterval(int64_t t_sweep_ns, const SweepSpan& span, double offset_s,
                                int64_t keyframe_ns) {
  const ImuInterval sweep = SweepImuInterval(t_sweep_ns, span, offset_s);
  return {std::min(keyframe_ns, sweep.begin_ns), std::max(keyframe_ns, sweep.end_ns)};
}

}  // namespace estimation
}  // namespace autocal
