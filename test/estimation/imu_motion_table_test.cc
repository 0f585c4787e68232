#include "autocal/estimation/imu_motion_table.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace estimation {
namespace {

const Eigen::Vector3d kGravity(0.0, 0.0, -9.80665);

// Smooth motion with exact derivatives: R = Exp(phi(t)), body rate Jr(phi) phi'.
struct Motion {
  Eigen::Vector3d p(double t) const {
    return {8.0 * t + 0.5 * std::sin(1.3 * t), 3.0 * std::cos(0.4 * t), 0.2 * std::sin(0.8 * t)};
  }
  Eigen::Vector3d v(double t) const {
    return {8.0 + 0.65 * std::cos(1.3 * t), -1.2 * std::sin(0.4 * t), 0.16 * std::cos(0.8 * t)};
  }
  Eigen::Vector3d a(double t) const {
    return {-0.845 * std::sin(1.3 * t), -0.48 * std::cos(0.4 * t), -0.128 * std::sin(0.8 * t)};
  }
  Eigen::Vector3d phi(double t) const {
    return {0.05 * std::sin(2.0 * t), 0.04 * std::cos(1.5 * t), 0.5 * t};
  }
  Eigen::Vector3d phi_dot(double t) const {
    return {0.1 * std::cos(2.0 * t), -0.06 * std::sin(1.5 * t), 0.5};
  }
  Eigen::Quaterniond q(double t) const { return geometry::Exp(phi(t)); }
  Eigen::Vector3d omega(double t) const { return geometry::RightJacobian(phi(t)) * phi_dot(t); }
};

sensors::ImuSamples Sample(const Motion& m, const Eigen::Vector3d& b_g,
                           const Eigen::Vector3d& b_a) {
  sensors::ImuSamples imu;
  for (int64_t t_ns = 0; t_ns <= SecondsToNs(3.0); t_ns += 5'000'000) {
    const double t = NsToSeconds(t_ns);
    imu.push_back({t_ns, m.omega(t) + b_g, m.q(t).conjugate() * (m.a(t) - kGravity) + b_a});
  }
  return imu;
}

// Checks table.At against the true motion from t_k at t_k + each of offsets_ns.
void ExpectTrueMotion(const Motion& motion, const ImuMotionTable& table, int64_t t_k,
                      const std::vector<int64_t>& offsets_ns) {
  const double tk = NsToSeconds(t_k);
  for (int64_t offset_ns : offsets_ns) {
    const int64_t t_ns = t_k + offset_ns;
    const double t = NsToSeconds(t_ns), dt = t - tk;
    const factors::PointMotion m = table.At(t_ns);
    const Eigen::Quaterniond q_k = motion.q(tk);
    EXPECT_NEAR(m.dt_s, dt, 1e-12);
    const Eigen::Quaterniond dq_true = q_k.conjugate() * motion.q(t);
    const Eigen::Vector3d dv_true = q_k.conjugate() * (motion.v(t) - motion.v(tk) - kGravity * dt);
    const Eigen::Vector3d dp_true =
        q_k.conjugate() *
        (motion.p(t) - motion.p(tk) - motion.v(tk) * dt - 0.5 * kGravity * dt * dt);
    // Midpoint integration of 5 ms steps: errors of order (rate change per step)^2.
    EXPECT_LT(geometry::AngularDistance(m.delta_q, dq_true), 2e-6) << "dt " << dt;
    EXPECT_LT((m.delta_v - dv_true).norm(), 1e-4) << "dt " << dt;
    EXPECT_LT((m.delta_p - dp_true).norm(), 1e-5) << "dt " << dt;
    EXPECT_LT((m.omega_rad_s - motion.omega(t)).norm(), 1e-5) << "dt " << dt;
  }
}

TEST(ImuMotionTable, MatchesTrueMotionInsideASweep) {
  const Motion motion;
  const Eigen::Vector3d b_g(0.01, -0.02, 0.005), b_a(0.1, 0.05, -0.08);
  const sensors::ImuSamples imu = Sample(motion, b_g, b_a);
  const int64_t t_k = 1'002'500'000;  // between two samples
  const ImuMotionTable table(imu, t_k, t_k + 110'000'000, b_g, b_a);
  ExpectTrueMotion(motion, table, t_k,
                   {0LL, 1'234'567LL, 50'000'000LL, 99'999'999LL, 110'000'000LL});
}

// A keyframe at a sweep's middle (Eq. P1c): the table reaches back from its origin as well as
// forward, with the true motion from the origin on both sides, and past the origin it is the
// table that starts there to rounding.
TEST(ImuMotionTable, MeasuresMotionFromAnOriginInsideTheTable) {
  const Motion motion;
  const Eigen::Vector3d b_g(0.01, -0.02, 0.005), b_a(0.1, 0.05, -0.08);
  const sensors::ImuSamples imu = Sample(motion, b_g, b_a);
  const int64_t t_begin = 1'002'500'000, t_k = t_begin + 52'345'678, t_end = t_begin + 110'000'000;
  const ImuMotionTable table(imu, t_begin, t_end, b_g, b_a, 0, t_k);
  ExpectTrueMotion(motion, table, t_k,
                   {t_begin - t_k, -51'000'000LL, -1'234'567LL, 0LL, 2'345'678LL, t_end - t_k});
  const ImuMotionTable forward(imu, t_k, t_end, b_g, b_a);
  for (int64_t t_ns = t_k; t_ns <= t_end; t_ns += 7'000'000) {
    const factors::PointMotion a = table.At(t_ns), b = forward.At(t_ns);
    EXPECT_EQ(a.dt_s, b.dt_s);
    EXPECT_LT(geometry::AngularDistance(a.delta_q, b.delta_q), 1e-13);
    EXPECT_LT((a.delta_v - b.delta_v).norm(), 1e-13);
    EXPECT_LT((a.delta_p - b.delta_p).norm(), 1e-13);
  }
  EXPECT_THROW(ImuMotionTable(imu, t_begin, t_end, b_g, b_a, 0, t_end + 1), Error);
  EXPECT_THROW(ImuMotionTable(imu, t_begin, t_end, b_g, b_a, 0, t_begin - 1), Error);
}

// Eq. P1c: the keyframe time is the IMU time of the middle of the sweep's points, the stamp
// for a sweep without point times.
TEST(KeyframeTime, SitsAtTheMiddleOfTheSweepsPoints) {
  EXPECT_EQ(KeyframeTime(1'000'000'000, SweepSpan{0.0, 0.1}, 0.025), 1'075'000'000);
  EXPECT_EQ(KeyframeTime(1'000'000'000, SweepSpan{-0.1, 0.0}, -0.01), 940'000'000);
  lidar::LidarSweep sweep;
  sweep.t_ns = 2'000'000'000;
  sweep.cloud.points = Eigen::Matrix3Xd::Ones(3, 3);
  EXPECT_EQ(KeyframeTime(sweep, 0.005), 2'005'000'000);
  sweep.cloud.time_s = Eigen::VectorXd(3);
  sweep.cloud.time_s << 0.08, 0.01, 0.05;
  EXPECT_EQ(KeyframeTime(sweep, 0.005), 2'050'000'000);
}

// The IMU interval a sweep's motion table must cover besides its keyframe: the points and the
// reference instant (point time 0), whichever side of the stamp they lie on.
TEST(SweepImuInterval, CoversThePointsAndTheReferenceInstant) {
  const ImuInterval start_stamped = SweepImuInterval(1'000'000'000, SweepSpan{0.0, 0.1}, 0.025);
  EXPECT_EQ(start_stamped.begin_ns, 1'025'000'000);
  EXPECT_EQ(start_stamped.end_ns, 1'125'000'000);
  const ImuInterval end_stamped = SweepImuInterval(1'000'000'000, SweepSpan{-0.1, 0.0}, -0.01);
  EXPECT_EQ(end_stamped.begin_ns, 890'000'000);
  EXPECT_EQ(end_stamped.end_ns, 990'000'000);
  const ImuInterval after_stamp = SweepImuInterval(1'000'000'000, SweepSpan{0.02, 0.08}, 0.0);
  EXPECT_EQ(after_stamp.begin_ns, 1'000'000'000);
  EXPECT_EQ(after_stamp.end_ns, 1'080'000'000);
}

// The deskew reaches farthest at the point farthest from the stamp: the last for a sweep
// stamped at its start, the first for one stamped at its end.
TEST(SweepSpan, ReachesFromTheStampToTheFarthestPoint) {
  const SweepSpan start_stamped{0.0, 0.1};
  EXPECT_EQ(start_stamped.farthest_s(), 0.1);
  EXPECT_EQ(start_stamped.reach_s(), 0.1);
  EXPECT_NEAR(start_stamped.length_s(), 0.1, 1e-17);
  const SweepSpan end_stamped{-0.1, -0.001};
  EXPECT_EQ(end_stamped.farthest_s(), -0.1);
  EXPECT_EQ(end_stamped.reach_s(), 0.1);
  EXPECT_NEAR(end_stamped.length_s(), 0.099, 1e-15);
  lidar::LidarSweep sweep;
  sweep.cloud.points = Eigen::Matrix3Xd::Ones(3, 3);
  EXPECT_EQ(SpanOf(sweep).reach_s(), 0.0);  // no point times: the stamp alone
  sweep.cloud.time_s = Eigen::VectorXd(3);
  sweep.cloud.time_s << -0.02, -0.09, -0.05;
  EXPECT_EQ(SpanOf(sweep).first_s, -0.09);
  EXPECT_EQ(SpanOf(sweep).last_s, -0.02);
}

// The true body rate's mean over [t - h, t + h] (Simpson's rule on 200 intervals).
Eigen::Vector3d MeanTrueRate(const Motion& motion, double t, double h) {
  Eigen::Vector3d sum = motion.omega(t - h) + motion.omega(t + h);
  for (int i = 1; i < 200; ++i) sum += (i % 2 == 1 ? 4.0 : 2.0) * motion.omega(t - h + h * i / 100);
  return sum / 600.0;
}

// Eq. P1b: with a rate window the rate is the gyroscope's mean over the window centred on the
// query, reaching past the table's ends as far as the samples go (the window narrows, still
// centred, only where they end); its white noise falls by the square root of the samples it
// spans; the deltas are those of the table without a window.
TEST(ImuMotionTable, AveragesTheRateOverACentredWindow) {
  const Motion motion;
  const Eigen::Vector3d b_g(0.01, -0.02, 0.005), b_a(0.1, 0.05, -0.08);
  sensors::ImuSamples imu = Sample(motion, b_g, b_a);
  const int64_t t_k = 1'002'500'000;
  const int64_t window_ns = 100'000'000;
  const ImuMotionTable table(imu, t_k, t_k + 110'000'000, b_g, b_a, window_ns);
  for (int64_t offset_ns : {0LL, 30'000'000LL, 60'000'000LL, 110'000'000LL}) {
    const int64_t t_ns = t_k + offset_ns;
    const Eigen::Vector3d mean = MeanTrueRate(motion, NsToSeconds(t_ns), 0.05);
    // Trapezoids of 5 ms on a smooth rate: errors of order 1e-7 rad/s.
    EXPECT_LT((table.At(t_ns).omega_rad_s - mean).norm(), 1e-6) << offset_ns;
  }
  // At the last sample the window narrows to nothing: the rate there.
  const ImuMotionTable at_end(imu, imu.back().t_ns - 50'000'000, imu.back().t_ns, b_g, b_a,
                              window_ns);
  EXPECT_LT((at_end.At(imu.back().t_ns).omega_rad_s - motion.omega(3.0)).norm(), 1e-9);
  const int64_t near_end = imu.back().t_ns - 20'000'000;
  EXPECT_LT(
      (at_end.At(near_end).omega_rad_s - MeanTrueRate(motion, NsToSeconds(near_end), 0.02)).norm(),
      1e-6);

  // Gyroscope white noise of 2.4e-3 rad/s a sample (a MEMS unit at 200 Hz): the instantaneous
  // rate carries all of it, the 100 ms mean about 1 / sqrt(21) of it (measured: 0.21).
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 2.4e-3);
  for (sensors::ImuSample& s : imu) s.gyro_rad_s += Eigen::Vector3d(noise(rng), noise(rng), 0.0);
  double instant_sq = 0.0, mean_sq = 0.0;
  int n = 0;
  for (int64_t t_ns = 1'000'000'000; t_ns < 2'800'000'000; t_ns += 100'000'000) {
    const ImuMotionTable plain(imu, t_ns, t_ns + 110'000'000, b_g, b_a);
    const ImuMotionTable windowed(imu, t_ns, t_ns + 110'000'000, b_g, b_a, window_ns);
    for (int64_t at : {t_ns, t_ns + 55'000'000, t_ns + 110'000'000}) {
      EXPECT_EQ(plain.At(at).delta_q.coeffs(), windowed.At(at).delta_q.coeffs());
      const Eigen::Vector3d truth = MeanTrueRate(motion, NsToSeconds(at), 0.05);
      instant_sq += (plain.At(at).omega_rad_s - truth).head<2>().squaredNorm();
      mean_sq += (windowed.At(at).omega_rad_s - truth).head<2>().squaredNorm();
      n += 2;
    }
  }
  const double ratio = std::sqrt(mean_sq / instant_sq);
  EXPECT_GT(std::sqrt(instant_sq / n), 1.5e-3);
  EXPECT_GT(ratio, 0.15);
  EXPECT_LT(ratio, 0.3);
}

TEST(ImuMotionTable, RefusesIntervalsOutsideTheSamples) {
  const Motion motion;
  const sensors::ImuSamples imu = Sample(motion, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  EXPECT_THROW(ImuMotionTable(imu, -1, 100, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()),
               Error);
  EXPECT_THROW(ImuMotionTable(imu, 2'900'000'000, 3'100'000'000, Eigen::Vector3d::Zero(),
                              Eigen::Vector3d::Zero()),
               Error);
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
