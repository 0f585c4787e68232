#include "autocal/estimation/initialization.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <iostream>
#include <random>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace estimation {
namespace {

using geometry::Exp;
constexpr double kGravity = 9.80665;

// An IMU orientation R_W_I(t) = Exp(phi(t)) with exact body rate Jr(phi) phi'.
struct RotationMotion {
  std::function<Eigen::Vector3d(double)> phi;
  std::function<Eigen::Vector3d(double)> phi_dot;
  Eigen::Quaterniond At(double t) const { return Exp(phi(t)); }
  Eigen::Vector3d Rate(double t) const { return geometry::RightJacobian(phi(t)) * phi_dot(t); }
};

// Turning in all three axes with a varying rate, after `still_s` seconds at rest.
RotationMotion RichMotion(double still_s) {
  RotationMotion m;
  auto s = [still_s](double t) { return std::max(0.0, t - still_s); };
  m.phi = [s](double t) {
    const double u = s(t);
    return Eigen::Vector3d(0.05 + 0.15 * std::sin(0.9 * u), -0.03 + 0.1 * std::sin(1.3 * u),
                           0.6 * std::sin(0.4 * u) + 0.3 * u - 0.2 * std::cos(1.7 * u) + 0.2);
  };
  m.phi_dot = [s, still_s](double t) {
    if (t < still_s) return Eigen::Vector3d::Zero().eval();
    const double u = s(t);
    return Eigen::Vector3d(0.135 * std::cos(0.9 * u), 0.13 * std::cos(1.3 * u),
                           0.24 * std::cos(0.4 * u) + 0.3 + 0.34 * std::sin(1.7 * u));
  };
  return m;
}

RotationMotion PlanarMotion() {
  RotationMotion m;
  m.phi = [](double t) { return Eigen::Vector3d(0.0, 0.0, 0.6 * std::sin(0.4 * t) + 0.3 * t); };
  m.phi_dot = [](double t) { return Eigen::Vector3d(0.0, 0.0, 0.24 * std::cos(0.4 * t) + 0.3); };
  return m;
}

sensors::ImuSamples SimulateImu(const RotationMotion& motion, double duration_s,
                                const Eigen::Vector3d& bias, double gyro_noise_rad_s,
                                uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  sensors::ImuSamples imu;
  for (int64_t t_ns = 0; t_ns <= SecondsToNs(duration_s); t_ns += 5'000'000) {
    const double t = NsToSeconds(t_ns);
    sensors::ImuSample s;
    s.t_ns = t_ns;
    s.gyro_rad_s =
        motion.Rate(t) + bias + gyro_noise_rad_s * Eigen::Vector3d(n(rng), n(rng), n(rng));
    s.accel_m_s2 = motion.At(t).conjugate() * Eigen::Vector3d(0.0, 0.0, kGravity) +
                   0.02 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    imu.push_back(s);
  }
  return imu;
}

// The gyro integral between instants inside IMU steps matches the true relative rotation
// (bias removed), is the identity over an empty interval, and composes; outside the log it
// throws.
TEST(IntegrateGyro, MatchesTheTrueRotationBetweenAnyTwoInstants) {
  const RotationMotion motion = RichMotion(0.0);
  const Eigen::Vector3d bias(0.01, -0.02, 0.005);
  const sensors::ImuSamples imu = SimulateImu(motion, 60.0, bias, 0.0, 1);
  for (const auto& [t0_s, t1_s] :
       {std::pair{0.0, 60.0}, std::pair{12.3456789, 12.3471}, std::pair{30.0021, 47.9999}}) {
    const Eigen::Quaterniond q = IntegrateGyro(imu, bias, SecondsToNs(t0_s), SecondsToNs(t1_s));
    const Eigen::Quaterniond truth = motion.At(t0_s).conjugate() * motion.At(t1_s);
    // Trapezoidal rates over 5 ms steps of a smooth motion: well below 1e-5 rad.
    EXPECT_LT(geometry::AngularDistance(q, truth), 1e-5) << t0_s << " " << t1_s;
  }
  const int64_t a = SecondsToNs(10.0012), b = SecondsToNs(20.5), c = SecondsToNs(33.3333);
  EXPECT_LT(
      geometry::AngularDistance(IntegrateGyro(imu, bias, a, b) * IntegrateGyro(imu, bias, b, c),
                                IntegrateGyro(imu, bias, a, c)),
      1e-12);
  EXPECT_EQ(IntegrateGyro(imu, bias, a, a).coeffs(), Eigen::Quaterniond::Identity().coeffs());
  EXPECT_THROW(IntegrateGyro(imu, bias, -1, a), Error);
  EXPECT_THROW(IntegrateGyro(imu, bias, a, SecondsToNs(61.0)), Error);
  EXPECT_THROW(IntegrateGyro(imu, bias, b, a), Error);
}

TEST(DetectStillStart, FindsBiasAndGravityDirection) {
  const RotationMotion motion = RichMotion(3.0);
  const Eigen::Vector3d bias(0.004, -0.002, 0.003);
  const sensors::ImuSamples imu = SimulateImu(motion, 10.0, bias, 0.002, 1);
  const StillStart still = DetectStillStart(imu);
  ASSERT_TRUE(still.found) << still.reason;
  EXPECT_LE(NsToSeconds(still.t_end_ns), 3.0);
  EXPECT_GE(NsToSeconds(still.t_end_ns - still.t_begin_ns), 2.0);
  // Mean of >= 400 samples with 0.002 rad/s noise: error well below 0.0005 rad/s (5 sigma).
  EXPECT_LT((still.gyro_bias_rad_s - bias).norm(), 5e-4)
      << still.gyro_bias_rad_s.transpose() << " vs " << bias.transpose();
  EXPECT_NEAR(still.gravity_m_s2, kGravity, 0.01);
  // Roll and pitch agree with the truth: gravity maps to -z in W.
  const Eigen::Vector3d up_in_I_true = motion.At(0.0).conjugate() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up_in_I_est = still.q_W_I.conjugate() * Eigen::Vector3d::UnitZ();
  EXPECT_LT(std::acos(std::min(1.0, up_in_I_true.dot(up_in_I_est))), 0.05 * kDegToRad);
}

TEST(DetectStillStart, ReportsWhenThereIsNoStillPeriod) {
  const sensors::ImuSamples imu =
      SimulateImu(RichMotion(0.0), 10.0, Eigen::Vector3d::Zero(), 0.002, 2);
  const StillStart still = DetectStillStart(imu);
  EXPECT_FALSE(still.found);
  EXPECT_FALSE(still.reason.empty());
}

// LiDAR relative rotations between sweep stamps (LiDAR clock) for a true extrinsic and
// offset, with optional rotation noise.
std::vector<RelativeRotation> LidarRotations(const RotationMotion& motion, double duration_s,
                                             const Eigen::Quaterniond& q_I_L, double offset_s,
                                             double noise_rad, uint32_t seed,
                                             double interval_s = 0.1) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<RelativeRotation> out;
  for (double s0 = 0.5; s0 + interval_s < duration_s - 0.5; s0 += 0.1) {
    const double s1 = s0 + interval_s;
    RelativeRotation r;
    r.t0_ns = SecondsToNs(s0);
    r.t1_ns = SecondsToNs(s1);
    const Eigen::Quaterniond q_I = motion.At(s0 + offset_s).conjugate() * motion.At(s1 + offset_s);
    r.q_0_1 = q_I_L.conjugate() * q_I * q_I_L *
              Exp(Eigen::Vector3d(noise_rad * n(rng), noise_rad * n(rng), noise_rad * n(rng)));
    out.push_back(r);
  }
  return out;
}

TEST(EstimateTimeOffset, RecoversOffsetFromAngularRates) {
  const RotationMotion motion = RichMotion(0.0);
  const Eigen::Quaterniond q_I_L = Exp(Eigen::Vector3d(0.05, -0.04, 1.5));
  const Eigen::Vector3d bias(0.003, 0.001, -0.002);
  const sensors::ImuSamples imu = SimulateImu(motion, 40.0, bias, 0.003, 3);
  for (double true_offset_s : {0.037, -0.052, 0.0}) {
    const auto rotations = LidarRotations(motion, 40.0, q_I_L, true_offset_s, 0.0005, 4);
    const TimeOffsetEstimate estimate = EstimateTimeOffset(rotations, imu, bias);
    ASSERT_TRUE(estimate.reliable) << estimate.reason;
    EXPECT_NEAR(estimate.offset_s, true_offset_s, 1e-3)
        << "correlation " << estimate.peak_correlation;
    EXPECT_EQ(estimate.candidate_offsets_s.size(), estimate.correlation.size());
  }
}

TEST(EstimateTimeOffset, ReportsConstantRateMotionAsUnreliable) {
  RotationMotion constant;
  constant.phi = [](double t) { return Eigen::Vector3d(0.0, 0.0, 0.2 * t); };
  constant.phi_dot = [](double) { return Eigen::Vector3d(0.0, 0.0, 0.2); };
  const sensors::ImuSamples imu = SimulateImu(constant, 30.0, Eigen::Vector3d::Zero(), 0.003, 5);
  const auto rotations =
      LidarRotations(constant, 30.0, Eigen::Quaterniond::Identity(), 0.03, 0.0005, 6);
  const TimeOffsetEstimate estimate = EstimateTimeOffset(rotations, imu, Eigen::Vector3d::Zero());
  EXPECT_FALSE(estimate.reliable);
  EXPECT_FALSE(estimate.reason.empty());
}

// Candidate offsets stay inside the search range, whose coverage by the IMU the intervals
// were checked for, also when the step does not divide it (0.1 / 0.006: the last whole step is
// 0.096 s; rounding the step count made it 0.102 s). Options that are not a positive range
// with a step inside it are refused by name (a negative range read past the correlation
// curve's end, a zero step overflowed the step count).
TEST(EstimateTimeOffset, ScansOnlyInsideTheSearchRange) {
  const RotationMotion motion = RichMotion(0.0);
  const sensors::ImuSamples imu = SimulateImu(motion, 20.0, Eigen::Vector3d::Zero(), 0.003, 3);
  const auto rotations =
      LidarRotations(motion, 20.0, Eigen::Quaterniond::Identity(), 0.02, 0.0005, 4);
  TimeOffsetOptions options;
  options.search_range_s = 0.1;
  options.step_s = 0.006;
  const TimeOffsetEstimate estimate =
      EstimateTimeOffset(rotations, imu, Eigen::Vector3d::Zero(), options);
  ASSERT_TRUE(estimate.reliable) << estimate.reason;
  EXPECT_NEAR(estimate.offset_s, 0.02, 2e-3);
  ASSERT_EQ(estimate.candidate_offsets_s.size(), 33u);
  EXPECT_NEAR(estimate.candidate_offsets_s.front(), -0.096, 1e-12);
  EXPECT_NEAR(estimate.candidate_offsets_s.back(), 0.096, 1e-12);
  for (const auto& [range_s, step_s] :
       {std::pair{-0.1, 0.001}, std::pair{0.0, 0.001}, std::pair{std::nan(""), 0.001},
        std::pair{61.0, 0.001}, std::pair{0.1, 0.0}, std::pair{0.1, -0.001},
        std::pair{0.1, std::nan("")}, std::pair{0.1, 0.2}}) {
    options.search_range_s = range_s;
    options.step_s = step_s;
    try {
      EstimateTimeOffset(rotations, imu, Eigen::Vector3d::Zero(), options);
      ADD_FAILURE() << "range " << range_s << " s, step " << step_s << " s accepted";
    } catch (const Error& e) {
      const std::string message = e.what();
      const std::string option = range_s > 0.0 && range_s <= 60.0 ? "step_s" : "search_range_s";
      EXPECT_NE(message.find("EstimateTimeOffset: " + option + " must lie in"), std::string::npos)
          << message;
    }
  }
}

// IMU rotations over intervals of 1 s (offset known) paired with the LiDAR's: longer
// intervals rotate more, so the same odometry noise disturbs the rotation axes less.
void RotationPairs(const RotationMotion& motion, const sensors::ImuSamples& imu,
                   const Eigen::Quaterniond& q_I_L, double offset_s, double noise_rad,
                   std::vector<Eigen::Quaterniond>* imu_rotations,
                   std::vector<Eigen::Quaterniond>* lidar_rotations) {
  for (const RelativeRotation& r :
       LidarRotations(motion, 20.0, q_I_L, offset_s, noise_rad, 7, /*interval_s=*/1.0)) {
    const int64_t offset_ns = SecondsToNs(offset_s);
    imu_rotations->push_back(
        IntegrateGyro(imu, Eigen::Vector3d::Zero(), r.t0_ns + offset_ns, r.t1_ns + offset_ns));
    lidar_rotations->push_back(r.q_0_1);
  }
}

TEST(SolveHandEyeRotation, RecoversExtrinsicRotation) {
  const RotationMotion motion = RichMotion(0.0);
  const sensors::ImuSamples imu = SimulateImu(motion, 20.0, Eigen::Vector3d::Zero(), 0.0, 8);
  const Eigen::Quaterniond q_I_L = Exp(Eigen::Vector3d(0.05, -0.04, 1.5));
  for (double noise_rad : {0.0, 0.001}) {
    std::vector<Eigen::Quaterniond> a, b;
    RotationPairs(motion, imu, q_I_L, 0.02, noise_rad, &a, &b);
    const HandEyeRotation result = SolveHandEyeRotation(a, b);
    ASSERT_TRUE(result.observable) << result.reason;
    const double error_deg = geometry::AngularDistance(result.q_I_L, q_I_L) * kRadToDeg;
    std::cout << "noise " << noise_rad << " rad: error " << error_deg << " deg, weakest axis "
              << result.weakest_axis_rotation_rad << " rad, std "
              << result.weakest_axis_std_rad * kRadToDeg << " deg\n";
    // Noise-free: only gyro integration error remains. With 1 mrad per axis on every LiDAR
    // rotation, the extrinsic's rotation about z is seen only through roll/pitch turns of
    // ~0.1 rad per 1 s interval: ~1 deg per pair, ~20 independent intervals -> ~0.2 deg.
    // The initializer only has to land inside the batch solver's basin (degrees).
    EXPECT_LT(error_deg, noise_rad == 0.0 ? 0.01 : 0.3) << "noise " << noise_rad;
  }
}

TEST(SolveHandEyeRotation, PlanarMotionIsReportedUnobservable) {
  const RotationMotion motion = PlanarMotion();
  const sensors::ImuSamples imu = SimulateImu(motion, 20.0, Eigen::Vector3d::Zero(), 0.0, 9);
  std::vector<Eigen::Quaterniond> a, b;
  RotationPairs(motion, imu, Exp(Eigen::Vector3d(0.05, -0.04, 1.5)), 0.0, 0.0, &a, &b);
  const HandEyeRotation result = SolveHandEyeRotation(a, b);
  EXPECT_FALSE(result.observable);
  EXPECT_LT(result.singular_value_ratio, 0.02);
}

// Pairs of a true extrinsic: IMU rotations Exp(w) with gyro noise, the LiDAR's
// R_I_L^T Exp(w) R_I_L with odometry noise (per axis).
struct NoisyPairs {
  Eigen::Quaterniond q_I_L = Exp(Eigen::Vector3d(0.5, 1.0, 1.5).normalized() * 0.5);
  std::vector<Eigen::Quaterniond> imu, lidar;
  std::mt19937 rng;
  std::normal_distribution<double> n{0.0, 1.0};

  explicit NoisyPairs(uint32_t seed) : rng(seed) {}
  Eigen::Vector3d Gauss() { return Eigen::Vector3d(n(rng), n(rng), n(rng)); }
  void Add(const Eigen::Vector3d& w, double gyro_noise_deg, double lidar_noise_deg) {
    const Eigen::Quaterniond a = Exp(w);
    imu.push_back(a * Exp(Eigen::Vector3d(Gauss() * gyro_noise_deg * kDegToRad)));
    lidar.push_back(q_I_L.conjugate() * a * q_I_L *
                    Exp(Eigen::Vector3d(Gauss() * lidar_noise_deg * kDegToRad)));
  }
  // A rotation by angle_deg about a random axis.
  void AddRandom(double angle_deg, double gyro_noise_deg, double lidar_noise_deg) {
    Add(Gauss().normalized() * angle_deg * kDegToRad, gyro_noise_deg, lidar_noise_deg);
  }
};

// Pairs that barely turn passed the scale-free ratio alone: 50 pairs of 0.01 deg with
// 0.02 deg of odometry noise had a ratio of 0.94 and were observable, 31.8 deg off (no
// rotation: 28.6 deg; 0.05 deg: 7.6 deg off). Their motion about the weakest axis stays below
// what noise fakes. The same noise on 10 deg pairs is observable, 0.04 deg off.
TEST(SolveHandEyeRotation, PairsAtTheNoiseLevelAreReportedUnobservable) {
  for (double angle_deg : {0.0, 0.01, 0.05}) {
    NoisyPairs pairs(3);
    for (int i = 0; i < 50; ++i) pairs.AddRandom(angle_deg, 0.0, 0.02);
    const HandEyeRotation result = SolveHandEyeRotation(pairs.imu, pairs.lidar);
    std::cout << angle_deg << " deg per pair: ratio " << result.singular_value_ratio << ", "
              << result.turning_pairs << " turning pairs, error "
              << geometry::AngularDistance(result.q_I_L, pairs.q_I_L) * kRadToDeg << " deg\n";
    EXPECT_GT(result.singular_value_ratio, 0.5);  // the ratio alone would accept them
    EXPECT_FALSE(result.observable) << angle_deg;
    EXPECT_NE(result.reason.find("does not rise above the noise"), std::string::npos)
        << result.reason;
  }
  NoisyPairs turning(3);
  for (int i = 0; i < 50; ++i) turning.AddRandom(10.0, 0.0, 0.02);
  const HandEyeRotation result = SolveHandEyeRotation(turning.imu, turning.lidar);
  ASSERT_TRUE(result.observable) << result.reason;
  EXPECT_EQ(result.turning_pairs, 50);
  EXPECT_LT(result.weakest_axis_std_rad * kRadToDeg, 0.1);
  EXPECT_LT(geometry::AngularDistance(result.q_I_L, turning.q_I_L) * kRadToDeg, 0.1);
}

// Twelve turns of 8-19 deg about the vertical and many pairs driving straight: noise alone
// rotates the straight pairs about every axis, which passed the ratio (1500 pairs with
// 0.03 deg of odometry noise: 0.021, observable, 23 deg off). Only the turns count as
// motion, and they turn about one axis. Also with gyro noise on the straight pairs, whose
// floor is then not isotropic (0.1 deg per axis, 10000 pairs).
TEST(SolveHandEyeRotation, PlanarTurnsAmongNoisyStraightPairsAreUnobservable) {
  for (const auto& [straight, gyro_noise_deg, lidar_noise_deg] :
       {std::tuple{1500, 0.0, 0.03}, std::tuple{3000, 0.0, 0.03}, std::tuple{10000, 0.05, 0.1},
        std::tuple{1500, 0.15, 0.3}}) {
    NoisyPairs pairs(5);
    for (int i = 0; i < 12; ++i) {
      pairs.Add(Eigen::Vector3d(0.0, 0.0, (8.0 + i) * kDegToRad), gyro_noise_deg, lidar_noise_deg);
    }
    for (int i = 0; i < straight; ++i)
      pairs.Add(Eigen::Vector3d::Zero(), gyro_noise_deg, lidar_noise_deg);
    const HandEyeRotation result = SolveHandEyeRotation(pairs.imu, pairs.lidar);
    std::cout << straight << " straight pairs, noise " << gyro_noise_deg << " / " << lidar_noise_deg
              << " deg: ratio " << result.singular_value_ratio << ", " << result.turning_pairs
              << " turning pairs, weakest axis " << result.weakest_axis_rotation_rad << " rad, std "
              << result.weakest_axis_std_rad * kRadToDeg << " deg\n";
    EXPECT_GT(result.singular_value_ratio, HandEyeOptions().min_singular_value_ratio);
    EXPECT_FALSE(result.observable) << straight;
    EXPECT_LT(result.turning_pairs, 20);
  }
}

TEST(SolveHandEyeTranslation, RecoversLeverAndHoldsUnexcitedAxes) {
  std::mt19937 rng(10);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Quaterniond q_I_L = Exp(Eigen::Vector3d(0.02, 0.03, -0.7));
  const Eigen::Vector3d p_I_L(0.4, -0.25, 0.6);
  const Eigen::Vector3d prior(0.3, -0.2, 0.5);
  for (bool planar : {false, true}) {
    std::vector<Eigen::Quaterniond> rotations;
    std::vector<Eigen::Vector3d> t_imu, t_lidar;
    for (int i = 0; i < 40; ++i) {
      const Eigen::Vector3d phi = planar ? Eigen::Vector3d(0.0, 0.0, 0.5 * u(rng))
                                         : 0.4 * Eigen::Vector3d(u(rng), u(rng), u(rng));
      const Eigen::Quaterniond q_a = Exp(phi);
      const Eigen::Vector3d t_a = 2.0 * Eigen::Vector3d(u(rng), u(rng), planar ? 0.0 : u(rng));
      // T_L = T_I_L^-1 T_I T_I_L.
      const Eigen::Vector3d t_b = q_I_L.conjugate() * (q_a * p_I_L + t_a - p_I_L);
      rotations.push_back(q_a);
      t_imu.push_back(t_a);
      t_lidar.push_back(t_b);
    }
    const HandEyeTranslation result =
        SolveHandEyeTranslation(rotations, t_imu, t_lidar, q_I_L, prior);
    if (!planar) {
      EXPECT_TRUE(result.observable.all());
      EXPECT_LT((result.p_I_L - p_I_L).norm(), 1e-9) << result.p_I_L.transpose();
    } else {
      EXPECT_TRUE(result.observable(0) && result.observable(1));
      EXPECT_FALSE(result.observable(2));
      EXPECT_LT((result.p_I_L.head<2>() - p_I_L.head<2>()).norm(), 1e-9);
      EXPECT_DOUBLE_EQ(result.p_I_L.z(), prior.z());
    }
  }
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
