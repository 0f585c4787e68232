#pragma once

// IMU motion from a keyframe to any instant shortly before or after it, for the many LiDAR
// points of a sweep: the preintegrated deltas (dR, dv, dp) of Eq. F1 are tabulated at the IMU
// samples once, and each query integrates only the last partial step. Biases are fixed at the
// values given (the keyframe's estimate), so a table is rebuilt when they move.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace estimation {

class ImuMotionTable {
 public:
  // Whether `imu` covers [t_begin_ns, t_end_ns] (an interval that does not run backwards), as
  // a table needs.
  static bool Covers(const sensors::ImuSamples& imu, int64_t t_begin_ns, int64_t t_end_ns);

  // Tabulates from t_begin_ns to t_end_ns (IMU clock), the motion relative to t_origin_ns (the
  // keyframe; t_begin_ns when not given), which must lie in that interval: before it the
  // deltas run backwards (docs/estimation.md, Eq. P1c). With rate_window_ns > 0 the body rate
  // At gives is the bias-corrected gyroscope's mean over that span centred on the query
  // (narrowed, still centred, where the samples end), whose white noise falls with the square
  // root of the span (docs/estimation.md, Eq. P1b); 0 gives the rate at the instant. Throws
  // autocal::Error when the samples do not cover the interval (Covers) or the origin lies
  // outside it.
  ImuMotionTable(const sensors::ImuSamples& imu, int64_t t_begin_ns, int64_t t_end_ns,
                 const Eigen::Vector3d& b_g, const Eigen::Vector3d& b_a, int64_t rate_window_ns = 0,
                 std::optional<int64_t> t_origin_ns = std::nullopt);

  int64_t t_begin_ns() const { return t_begin_ns_; }
  int64_t t_end_ns() const { return t_end_ns_; }

  // Motion from the origin to t_ns (clamped into the tabulated interval), with the
  // bias-corrected body rate at t_ns (or about it, rate_window_ns). The signal is linear
  // between samples, so inside a step the partial step integrates the mean of the rates at its
  // two ends, and the rate at t_ns is interpolated.
  factors::PointMotion At(int64_t t_ns) const;

 private:
  struct Node {
    int64_t t_ns;
    Eigen::Quaterniond delta_q;
    Eigen::Vector3d delta_v;
    Eigen::Vector3d delta_p;
    // Bias-corrected rate and specific force where the step starting here begins, and their
    // change per second along the step (zero on the terminal node).
    Eigen::Vector3d gyro, accel;
    Eigen::Vector3d gyro_slope, accel_slope;
  };
  // Re-expresses every node's deltas from t_origin_ns_ instead of t_begin_ns_.
  void Rebase();
  // Advances n's deltas by dt seconds along its step.
  static void Step(double dt, Node* n);
  // The node of the step holding t_ns (within the table), advanced to t_ns.
  Node NodeAt(int64_t t_ns) const;
  // The mean rate of Eq. P1b about t_ns; the rate at t_ns when no window fits.
  Eigen::Vector3d MeanRate(int64_t t_ns, const Eigen::Vector3d& at_t) const;
  // The integral of the bias-corrected gyroscope from the first rate knot to t_ns.
  Eigen::Vector3d GyroIntegral(int64_t t_ns) const;

  // A knot of the piecewise-linear gyroscope signal and its integral up to the knot.
  struct RateKnot {
    int64_t t_ns;
    Eigen::Vector3d gyro;      // bias-corrected
    Eigen::Vector3d integral;  // from the first knot
  };

  int64_t t_origin_ns_;  // the keyframe: motion is relative to it
  int64_t t_begin_ns_;
  int64_t t_end_ns_;
  int64_t rate_window_ns_;
  std::vector<Node> nodes_;
  std::vector<RateKnot> rate_knots_;  // over the table and half a window on each side
};

// The times of a sweep's first and last points after its stamp, both 0 when its points carry
// no time; negative for a sweep stamped at its end. Read from the cloud once (SpanOf) and
// kept with the sweep: its keyframe time, IMU interval and deskew span follow from them.
struct SweepSpan {
  double first_s = 0.0;
  double last_s = 0.0;
  double length_s() const { return last_s - first_s; }
  // The time of the point farthest from the stamp (where the deskew reaches farthest), and its
  // distance from the stamp.
  double farthest_s() const { return std::abs(first_s) > std::abs(last_s) ? first_s : last_s; }
  double reach_s() const { return std::abs(farthest_s()); }
};
SweepSpan SpanOf(const lidar::LidarSweep& sweep);

// A sweep's keyframe time: for a sweep stamped t_sweep_ns (LiDAR clock) whose points span
// `span`, at LiDAR-IMU time offset offset_s, the IMU time of the span's middle, where the
// attitude error its points share through their motion table is smallest (docs/estimation.md,
// Eq. P1c).
int64_t KeyframeTime(int64_t t_sweep_ns, const SweepSpan& span, double offset_s);
int64_t KeyframeTime(const lidar::LidarSweep& sweep, double offset_s);

// The IMU interval of the same sweep's points and its reference instant (point time 0), which
// its motion table covers together with its keyframe.
struct ImuInterval {
  int64_t begin_ns = 0;
  int64_t end_ns = 0;
};
ImuInterval SweepImuInterval(int64_t t_sweep_ns, const SweepSpan& span, double offset_s);
// The interval a motion table of that sweep from its keyframe at keyframe_ns covers: the
// sweep's IMU interval and the keyframe.
ImuInterval MotionTableInterval(int64_t t_sweep_ns, const SweepSpan& span, double offset_s,
                                int64_t keyframe_ns);

}  // namespace estimation
}  // namespace autocal
