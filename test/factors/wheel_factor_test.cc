#include "autocal/factors/wheel_factor.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/factors/gnss_factor.h"
#include "autocal/factors/imu_factor.h"
#include "autocal/geometry/manifolds.h"
#include "factors/factor_test_utils.h"
#include "sensors/imu_test_trajectory.h"

namespace autocal {
namespace factors {
namespace {

const Eigen::Vector3d kGravity(0.0, 0.0, -9.80665);

// Everything a wheel residual reads, as parameter blocks.
struct WheelBlocks {
  Eigen::Quaterniond q_W_I = Eigen::Quaterniond::Identity();
  Eigen::Vector3d v_W_I = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_g = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_I_V = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_I_V = Eigen::Vector3d::Zero();
  double r_l = 0.33;
  double r_r = 0.33;
  double track_width = 1.6;

  std::vector<double*> Pointers(bool shared_radius) {
    std::vector<double*> p = {q_W_I.coeffs().data(), v_W_I.data(), b_g.data(),
                              q_I_V.coeffs().data(), p_I_V.data(), &r_l};
    if (!shared_radius) p.push_back(&r_r);
    p.push_back(&track_width);
    return p;
  }
};

std::vector<const ceres::Manifold*> Manifolds(const ceres::Manifold* quaternion, bool shared) {
  std::vector<const ceres::Manifold*> m = {quaternion, nullptr, nullptr,
                                           quaternion, nullptr, nullptr};
  if (!shared) m.push_back(nullptr);
  m.push_back(nullptr);
  return m;
}

// A car whose rear-axle centre V moves without side slip: in V it has forward speed v and
// yaw rate w (piecewise constant), an IMU mounted at T_I_V with bias b_g. Returns the wheel
// measurement and the IMU state of that instant.
struct CarInstant {
  WheelMeasurement measurement;
  Eigen::Quaterniond q_W_I;
  Eigen::Vector3d v_W_I;
};

CarInstant SimulateCar(const Eigen::Quaterniond& q_W_V, double speed_m_s, double yaw_rate_rad_s,
                       const WheelBlocks& truth) {
  const Eigen::Vector3d v_V(speed_m_s, 0.0, 0.0);
  const Eigen::Vector3d w_V(0.0, 0.0, yaw_rate_rad_s);
  // p_W_I = p_W_V + R_W_V p_V_I with p_V_I = -R_I_V^T p_I_V.
  const Eigen::Vector3d p_V_I = -(truth.q_I_V.conjugate() * truth.p_I_V);
  CarInstant out;
  out.q_W_I = q_W_V * truth.q_I_V.conjugate();
  out.v_W_I = q_W_V * (v_V + w_V.cross(p_V_I));
  out.measurement.gyro_rad_s = truth.q_I_V * w_V + truth.b_g;
  // Eq. F20 solved for the wheel rates.
  const double half_b = 0.5 * truth.track_width;
  out.measurement.left_rad_s = (speed_m_s - yaw_rate_rad_s * half_b) / truth.r_l;
  out.measurement.right_rad_s = (speed_m_s + yaw_rate_rad_s * half_b) / truth.r_r;
  return out;
}

WheelBlocks RandomCalibration(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  WheelBlocks b;
  b.q_I_V = geometry::Exp(Eigen::Vector3d(0.1 * u(*rng), 0.1 * u(*rng), 3.0 * u(*rng)));
  b.p_I_V = Eigen::Vector3d(1.2 * u(*rng), 0.3 * u(*rng), 0.5 * u(*rng));
  b.r_l = 0.33 + 0.02 * u(*rng);
  b.r_r = 0.33 + 0.02 * u(*rng);
  b.track_width = 1.6 + 0.1 * u(*rng);
  b.b_g = Eigen::Vector3d(u(*rng), u(*rng), u(*rng)) * 0.01;
  return b;
}

TEST(WheelFactor, ResidualVanishesAtGroundTruth) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    WheelBlocks truth = RandomCalibration(&rng);
    const CarInstant car =
        SimulateCar(Eigen::Quaterniond::UnitRandom(), 15.0 * u(rng), 0.5 * u(rng), truth);
    WheelBlocks state = truth;
    state.q_W_I = car.q_W_I;
    state.v_W_I = car.v_W_I;
    for (bool shared : {false, true}) {
      if (shared) state.r_r = state.r_l;
      WheelFactorOptions options;
      options.shared_radius = shared;
      if (trial % 2 == 1) {  // the yaw row's sigma following the track (Eq. F22b)
        options.yaw_row_track_m = 1.5;
        options.yaw_rate_gyro_sigma_rad_s = 0.004;
      }
      // The yaw row about the measured turning axis (Eq. K13c), here V's true up axis.
      if (trial % 3 == 2) options.yaw_axis_I = truth.q_I_V * Eigen::Vector3d::UnitZ();
      WheelMeasurement m = car.measurement;
      if (trial % 4 >= 2) {
        // The gyro reading is a span's mean (Eq. K13b): the yaw row takes the wheels' over the
        // span, in which the car drove 3 m/s faster, while the instant's rates turn 0.2 rad/s
        // faster at the reading's speed. Either row taking the other's rates leaves a residual.
        const double yaw_rate = (truth.q_I_V.conjugate() * (m.gyro_rad_s - truth.b_g)).z();
        const double half_b = 0.5 * truth.track_width;
        const double speed = 0.5 * (m.left_rad_s * truth.r_l + m.right_rad_s * truth.r_r);
        const auto rates = [&](double v, double w) {
          return Eigen::Vector2d((v - w * half_b) / truth.r_l, (v + w * half_b) / truth.r_r);
        };
        m.yaw_row_rad_s = rates(speed + 3.0, yaw_rate);
        const Eigen::Vector2d instant = rates(speed, yaw_rate + 0.2);
        m.left_rad_s = instant(0);
        m.right_rad_s = instant(1);
      }
      if (shared) {
        m.right_rad_s *= truth.r_r / truth.r_l;
        if (m.yaw_row_rad_s) (*m.yaw_row_rad_s)(1) *= truth.r_r / truth.r_l;
      }
      const WheelFactor factor(m, options);
      Eigen::Vector4d residual;
      const std::vector<double*> blocks = state.Pointers(shared);
      ASSERT_TRUE(factor.Evaluate(blocks.data(), residual.data(), nullptr));
      EXPECT_LT(residual.norm(), 1e-9)
          << "trial " << trial << ", shared " << shared << ": " << residual.transpose();
    }
  }
}

TEST(WheelFactor, JacobiansPassGradientCheckerAndMatchAutodiff) {
  const geometry::RightQuaternionManifold quaternion;
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    WheelBlocks state = RandomCalibration(&rng);
    state.q_W_I = Eigen::Quaterniond::UnitRandom();
    state.v_W_I = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 15.0;
    WheelMeasurement m;
    m.left_rad_s = 40.0 * u(rng);
    m.right_rad_s = 40.0 * u(rng);
    m.gyro_rad_s = Eigen::Vector3d(u(rng), u(rng), u(rng));
    if (trial % 5 < 3) m.yaw_row_rad_s = Eigen::Vector2d(40.0 * u(rng), 40.0 * u(rng));
    WheelFactorOptions options;
    options.non_holonomic = trial % 2 == 0;
    options.shared_radius = trial % 4 == 1;
    options.lateral_sigma_m_s = 0.03;  // distinct rows: a swapped sigma fails the comparison
    options.vertical_sigma_m_s = 0.11;
    if (trial % 3 != 0) {  // the yaw row's sigma following the track (Eq. F22b)
      options.yaw_row_track_m = 1.5 + 0.2 * u(rng);
      options.yaw_rate_gyro_sigma_rad_s = trial % 3 == 1 ? 0.0 : 0.006;
    }
    if (trial % 4 >= 2) {  // the yaw row about a measured turning axis (Eq. K13c)
      options.yaw_axis_I = Eigen::Vector3d(u(rng), u(rng), 2.0 + u(rng)).normalized();
    }
    const std::string context = "trial " + std::to_string(trial);
    const WheelFactor analytic(m, options);
    std::vector<double*> blocks = state.Pointers(options.shared_radius);
    test::ExpectGradientCheckPasses(analytic, Manifolds(&quaternion, options.shared_radius), blocks,
                                    1e-6, context);
    if (!options.shared_radius) {
      std::unique_ptr<ceres::CostFunction> autodiff(WheelResidual::CreateAutoDiff(m, options));
      test::ExpectSameJacobians(analytic, *autodiff, Manifolds(&quaternion, false), blocks, 1e-9,
                                context);
    }
  }
}

TEST(WheelFactor, RejectsBadInputAndInvalidTrackWidth) {
  WheelMeasurement m;
  m.left_rad_s = std::nan("");
  EXPECT_THROW(WheelFactor(m, WheelFactorOptions{}), Error);
  WheelFactorOptions bad;
  bad.speed_sigma_m_s = 0.0;
  EXPECT_THROW(WheelFactor(WheelMeasurement{}, bad), Error);
  const WheelFactor factor(WheelMeasurement{}, WheelFactorOptions{});
  // The autodiff twin agrees: a non-positive track is an invalid step, not an inf or NaN.
  const std::unique_ptr<ceres::CostFunction> twin(
      WheelResidual::CreateAutoDiff(WheelMeasurement{}, WheelFactorOptions{}));
  for (double track_width : {-1.0, 0.0}) {
    WheelBlocks state;
    state.track_width = track_width;
    Eigen::Vector4d residual;
    const std::vector<double*> blocks = state.Pointers(false);
    EXPECT_FALSE(factor.Evaluate(blocks.data(), residual.data(), nullptr)) << track_width;
    EXPECT_FALSE(twin->Evaluate(blocks.data(), residual.data(), nullptr)) << track_width;
  }
}

// The yaw row reads the body rate about yaw_axis_I as given (Eq. K13c): every wheel form
// refuses an axis that is neither zero nor unit, which would scale the row or make it NaN.
TEST(WheelFactor, EveryFormRefusesAYawAxisThatIsNotUnit) {
  const auto build = [](const Eigen::Vector3d& axis) {
    WheelFactorOptions options;
    options.yaw_axis_I = axis;
    const WheelFactor factor(WheelMeasurement{}, options);
    const std::unique_ptr<ceres::CostFunction> speeds(WheelSpeedResidual::Create({}, options));
    const std::unique_ptr<ceres::CostFunction> twist(OdometryTwistResidual::Create({}, options));
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (const Eigen::Vector3d& bad :
       {Eigen::Vector3d(0.0, 0.0, 2.0), Eigen::Vector3d(0.0, 0.0, 1.0 + 1e-4),
        Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(nan, 0.0, 1.0),
        Eigen::Vector3d(0.0, std::numeric_limits<double>::infinity(), 0.0)}) {
    WheelFactorOptions options;
    options.yaw_axis_I = bad;
    EXPECT_THROW(WheelFactor(WheelMeasurement{}, options), Error) << bad.transpose();
    EXPECT_THROW(WheelSpeedResidual::Create(WheelSpeedMeasurement{}, options), Error)
        << bad.transpose();
    EXPECT_THROW(OdometryTwistResidual::Create(OdometryMeasurement{}, options), Error)
        << bad.transpose();
  }
  try {
    build(Eigen::Vector3d(0.0, 0.0, 2.0));
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("yaw_axis_I"), std::string::npos) << e.what();
  }
  // Zero (V's up axis), a normalised axis and one a rounding off unit are accepted.
  EXPECT_NO_THROW(build(Eigen::Vector3d::Zero()));
  EXPECT_NO_THROW(build(Eigen::Vector3d(0.1, -0.2, 1.0).normalized()));
  EXPECT_NO_THROW(build(Eigen::Vector3d(0.0, 0.0, 1.0 + 1e-9)));
}

// Left/right radii and track width recovered from noisy encoder rates with known states,
// the car driving straight and through left and right turns at several speeds.
// `car` with noise on its wheel rates, as a state (the truth's calibration at its pose) and a
// measurement.
void AddNoisyInstant(CarInstant car, const WheelBlocks& truth,
                     std::normal_distribution<double>* noise, std::mt19937* rng,
                     std::vector<WheelBlocks>* states, std::vector<WheelMeasurement>* measured) {
  car.measurement.left_rad_s += (*noise)(*rng);
  car.measurement.right_rad_s += (*noise)(*rng);
  WheelBlocks state = truth;
  state.q_W_I = car.q_W_I;
  state.v_W_I = car.v_W_I;
  states->push_back(state);
  measured->push_back(car.measurement);
}

// One WheelFactor per state on the shared radius and track blocks; the blocks before
// `first_free` (5: radii and track free; 7: the track alone) held.
void AddWheelRows(std::vector<WheelBlocks>* states, const std::vector<WheelMeasurement>& measured,
                  const WheelFactorOptions& options, int first_free, double* r_l, double* r_r,
                  double* track_width, ceres::Problem* problem) {
  for (size_t k = 0; k < states->size(); ++k) {
    std::vector<double*> blocks = (*states)[k].Pointers(false);
    blocks[5] = r_l;
    blocks[6] = r_r;
    blocks[7] = track_width;
    problem->AddResidualBlock(WheelFactor::Create(measured[k], options), nullptr, blocks);
    for (int b = 0; b < first_free; ++b) problem->SetParameterBlockConstant(blocks[b]);
  }
}

TEST(WheelFactor, RecoversRadiiAndTrackWidth) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const sensors::WheelConfig config;  // encoder noise sigma
  std::normal_distribution<double> noise(0.0, config.noise_rad_s);
  WheelBlocks truth = RandomCalibration(&rng);
  const WheelFactorOptions options = WheelFactorOptions::FromEncoderNoise(config, 0.33, 1.6);
  std::vector<WheelBlocks> states;
  std::vector<WheelMeasurement> measurements;
  for (int k = 0; k < 400; ++k) {
    const double speed = 2.0 + 12.0 * (0.5 + 0.5 * u(rng));
    const double yaw_rate = 0.4 * u(rng);
    CarInstant car = SimulateCar(Eigen::Quaterniond::UnitRandom(), speed, yaw_rate, truth);
    AddNoisyInstant(car, truth, &noise, &rng, &states, &measurements);
  }
  double r_l = 0.33, r_r = 0.33, track_width = 1.6;
  ceres::Problem problem;
  AddWheelRows(&states, measurements, options, 5, &r_l, &r_r, &track_width, &problem);
  ceres::Solver::Options solver;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  EXPECT_NEAR(r_l, truth.r_l, 1e-3) << summary.BriefReport();
  EXPECT_NEAR(r_r, truth.r_r, 1e-3) << summary.BriefReport();
  EXPECT_NEAR(track_width, truth.track_width, 1e-2) << summary.BriefReport();
}

// Errors in variables (Eq. F22b): wheels far noisier than the gyro (0.3 rad/s per wheel, an
// exact gyro) and the track alone free. With the yaw row's sigma fixed the wheels' noise
// attenuates 1 / b: the track comes out long by about the noise's share of the rate
// difference's power. With the sigma following the track it comes out within 3 of its sigma.
TEST(WheelFactor, ASigmaFollowingTheTrackRemovesTheAttenuation) {
  std::mt19937 rng(47);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  sensors::WheelConfig config;
  config.noise_rad_s = 0.3;
  std::normal_distribution<double> noise(0.0, config.noise_rad_s);
  const WheelBlocks truth;  // r 0.33 m, b 1.6 m, identity mount
  std::vector<WheelBlocks> states;
  std::vector<WheelMeasurement> measurements;
  double power = 0.0;  // mean square of the true rate difference r (w_r - w_l), (m/s)^2
  for (int k = 0; k < 4000; ++k) {
    const double yaw_rate = 0.3 * u(rng);
    CarInstant car = SimulateCar(Eigen::Quaterniond::Identity(), 8.0, yaw_rate, truth);
    power += std::pow(yaw_rate * truth.track_width, 2) / 4000.0;
    AddNoisyInstant(car, truth, &noise, &rng, &states, &measurements);
  }
  const auto solve = [&](const WheelFactorOptions& options, double* sigma_m) {
    double r_l = truth.r_l, r_r = truth.r_r, track_width = truth.track_width;
    ceres::Problem problem;
    AddWheelRows(&states, measurements, options, 7, &r_l, &r_r, &track_width, &problem);
    ceres::Solver::Options solver;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    ceres::Covariance covariance{ceres::Covariance::Options()};
    std::vector<std::pair<const double*, const double*>> pairs = {{&track_width, &track_width}};
    EXPECT_TRUE(covariance.Compute(pairs, &problem));
    covariance.GetCovarianceBlock(&track_width, &track_width, sigma_m);
    *sigma_m = std::sqrt(*sigma_m);
    return track_width;
  };
  WheelFactorOptions fixed = WheelFactorOptions::FromEncoderNoise(config, 0.33, 1.6);
  WheelFactorOptions following = fixed;
  following.yaw_row_track_m = 1.6;
  double sigma_fixed = 0.0, sigma_following = 0.0;
  const double b_fixed = solve(fixed, &sigma_fixed);
  const double b_following = solve(following, &sigma_following);
  // Attenuation of 1 / b: noise power 2 (r s)^2 against the signal's.
  const double noise_power = 2.0 * std::pow(truth.r_l * config.noise_rad_s, 2);
  const double expected_long = truth.track_width * noise_power / power;
  std::cout << "track " << b_fixed << " m (sigma " << sigma_fixed << ") with a fixed sigma, "
            << b_following << " m (sigma " << sigma_following << ") following the track; "
            << "expected attenuation " << expected_long << " m\n";
  EXPECT_GT(b_fixed - truth.track_width, 5.0 * sigma_fixed);
  EXPECT_NEAR(b_fixed - truth.track_width, expected_long, 0.3 * expected_long);
  EXPECT_LT(std::abs(b_following - truth.track_width), 3.0 * sigma_following);
}

// The course's intrinsic-calibration example: a car moving along a line, an encoder on the
// rear wheels (v = w R), GNSS positions; the wheel radius is estimated together with the
// states. Here the motion model is the IMU factor between keyframes.
TEST(WheelFactor, CourseExampleRecoversRadiusWithTheStates) {
  constexpr double kTrueRadius = 0.317;
  constexpr int kKeyframes = 21;
  constexpr int64_t kKeyframePeriodNs = 100'000'000;
  test::SmoothTrajectory::Curve position, rotation;
  position.c1 = Eigen::Vector3d(6.0, 0.0, 0.0);
  position.c2 = Eigen::Vector3d(1.0, 0.0, 0.0);
  position.amplitude = {Eigen::Vector3d(1.5, 0.0, 0.0)};
  position.frequency_rad_s = {Eigen::Vector3d(2.0, 0.0, 0.0)};
  position.phase = {Eigen::Vector3d::Zero()};
  const test::SmoothTrajectory car(position, rotation);
  const sensors::ImuSamples imu = test::SampleImu(car, 0, 5'000'000, 420, kGravity);

  std::mt19937 rng(3);
  std::normal_distribution<double> gnss_noise(0.0, 0.05), wheel_noise(0.0, 0.02);
  struct Keyframe {
    Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
    Eigen::Vector3d p, v, b_g = Eigen::Vector3d::Zero(), b_a = Eigen::Vector3d::Zero();
  };
  std::vector<Keyframe> keyframes(kKeyframes);
  double radius = 0.30;  // nominal guess, 5% off
  double track_width = 1.6;
  Eigen::Vector3d p_I_A = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_I_V = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_I_V = Eigen::Vector3d::Zero();
  ceres::Problem problem;
  WheelFactorOptions wheel_options;
  wheel_options.shared_radius = true;
  for (int k = 0; k < kKeyframes; ++k) {
    const double t = NsToSeconds(k * kKeyframePeriodNs);
    Keyframe& kf = keyframes[k];
    kf.p = car.p_W_I(t) + Eigen::Vector3d(0.5, 0.2, -0.1);  // initial guesses off the truth
    kf.v = Eigen::Vector3d(5.0, 0.0, 0.0);
    GnssMeasurement fix;
    fix.p_W_A = car.p_W_I(t) + Eigen::Vector3d(gnss_noise(rng), gnss_noise(rng), gnss_noise(rng));
    fix.sigma_enu_m = Eigen::Vector3d::Constant(0.05);
    problem.AddResidualBlock(GnssFactor::Create(fix), nullptr, kf.q.coeffs().data(), kf.p.data(),
                             p_I_A.data());
    WheelMeasurement wheel;
    const double speed = car.v_W_I(t).x();
    wheel.left_rad_s = speed / kTrueRadius + wheel_noise(rng);
    wheel.right_rad_s = speed / kTrueRadius + wheel_noise(rng);
    problem.AddResidualBlock(WheelFactor::Create(wheel, wheel_options), nullptr,
                             {kf.q.coeffs().data(), kf.v.data(), kf.b_g.data(),
                              q_I_V.coeffs().data(), p_I_V.data(), &radius, &track_width});
    if (k > 0) {
      sensors::ImuPreintegration pim{sensors::ImuNoise(), sensors::PreintegrationOptions()};
      pim.Integrate(imu, (k - 1) * kKeyframePeriodNs, k * kKeyframePeriodNs);
      Keyframe& prev = keyframes[k - 1];
      problem.AddResidualBlock(
          ImuFactor::Create(pim), nullptr,
          {prev.q.coeffs().data(), prev.p.data(), prev.v.data(), prev.b_g.data(), prev.b_a.data(),
           kf.q.coeffs().data(), kf.p.data(), kf.v.data(), kf.b_g.data(), kf.b_a.data()});
    }
  }
  // Only positions, velocities and the radius are estimated (the course's state [p, v, R]).
  for (Keyframe& kf : keyframes) {
    problem.SetParameterBlockConstant(kf.q.coeffs().data());
    problem.SetParameterBlockConstant(kf.b_g.data());
    problem.SetParameterBlockConstant(kf.b_a.data());
  }
  for (double* fixed : {p_I_A.data(), q_I_V.coeffs().data(), p_I_V.data(), &track_width}) {
    problem.SetParameterBlockConstant(fixed);
  }
  ceres::Solver::Options options;
  options.max_num_iterations = 50;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
  EXPECT_NEAR(radius, kTrueRadius, 1e-3) << summary.BriefReport();
  for (int k = 0; k < kKeyframes; k += 5) {
    const double t = NsToSeconds(k * kKeyframePeriodNs);
    EXPECT_LT((keyframes[k].v - car.v_W_I(t)).norm(), 0.05) << "keyframe " << k;
    EXPECT_LT((keyframes[k].p - car.p_W_I(t)).norm(), 0.05) << "keyframe " << k;
  }
}

// ---- the other wheel forms: linear speeds (Eq. F25) and the controller's twist (Eq. F26) ----

// The intrinsics of the two other forms, random around nominal.
struct FormIntrinsics {
  double scale_left = 1.0;
  double scale_right = 1.0;
  double speed_scale = 1.0;           // k_v
  double effective_track_m = 0.9;     // b_eff
  double controller_track_m = 0.555;  // b_ctrl, a constant of the measurement
};

FormIntrinsics RandomIntrinsics(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  FormIntrinsics f;
  f.scale_left = 1.0 + 0.05 * u(*rng);
  f.scale_right = 1.0 + 0.05 * u(*rng);
  f.speed_scale = 0.95 + 0.05 * u(*rng);
  f.effective_track_m = 0.9 + 0.3 * u(*rng);
  f.controller_track_m = 0.555 + 0.1 * u(*rng);
  return f;
}

// The parameter blocks of a form's residual: the state's five, then the form's intrinsics.
std::vector<double*> SpeedBlocks(WheelBlocks* s, FormIntrinsics* f) {
  return {s->q_W_I.coeffs().data(), s->v_W_I.data(), s->b_g.data(),   s->q_I_V.coeffs().data(),
          s->p_I_V.data(),          &f->scale_left,  &f->scale_right, &s->track_width};
}
std::vector<double*> TwistBlocks(WheelBlocks* s, FormIntrinsics* f) {
  return {s->q_W_I.coeffs().data(), s->v_W_I.data(), s->b_g.data(),        s->q_I_V.coeffs().data(),
          s->p_I_V.data(),          &f->speed_scale, &f->effective_track_m};
}

// What the wheels of a car moving with speed v and yaw rate w (in V) report in each form: the
// forward models of Eq. F25 and F26 solved for the measurement.
WheelSpeedMeasurement SpeedsOf(double v, double w, const Eigen::Vector3d& gyro,
                               const WheelBlocks& truth, const FormIntrinsics& f) {
  WheelSpeedMeasurement m;
  m.left_m_s = (v - 0.5 * w * truth.track_width) / f.scale_left;
  m.right_m_s = (v + 0.5 * w * truth.track_width) / f.scale_right;
  m.gyro_rad_s = gyro;
  return m;
}
OdometryMeasurement TwistOf(double v, double w, const Eigen::Vector3d& gyro,
                            const FormIntrinsics& f) {
  OdometryMeasurement m;
  m.speed_m_s = v / f.speed_scale;
  m.yaw_rate_rad_s = w * f.effective_track_m / (f.speed_scale * f.controller_track_m);
  m.controller_track_m = f.controller_track_m;
  m.gyro_rad_s = gyro;
  return m;
}

TEST(WheelForms, ResidualsVanishAtGroundTruth) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    WheelBlocks truth = RandomCalibration(&rng);
    FormIntrinsics f = RandomIntrinsics(&rng);
    const double v = 15.0 * u(rng);
    const double w = 0.8 * u(rng);
    const CarInstant car = SimulateCar(Eigen::Quaterniond::UnitRandom(), v, w, truth);
    WheelBlocks state = truth;
    state.q_W_I = car.q_W_I;
    state.v_W_I = car.v_W_I;
    const Eigen::Vector3d& gyro = car.measurement.gyro_rad_s;
    WheelFactorOptions options;
    options.non_holonomic = trial % 2 == 0;
    if (trial % 5 >= 2) {  // the yaw row's sigma following the track, b or b_eff (Eq. F22b)
      options.yaw_row_track_m = 1.5;
      options.yaw_rate_gyro_sigma_rad_s = 0.004;
    }
    // The yaw row about the measured turning axis (Eq. K13c), here V's true up axis.
    const bool yaw_axis = trial % 3 != 0;
    if (yaw_axis) options.yaw_axis_I = truth.q_I_V * Eigen::Vector3d::UnitZ();
    WheelSpeedMeasurement wheel_speeds = SpeedsOf(v, w, gyro, truth, f);
    if (trial % 4 >= 2) {
      // The gyro reading is a span's mean (Eq. K13b): the yaw row takes the wheels' speeds over
      // the span, in which the car drove 3 m/s faster, while the instant's speeds turn 0.2 rad/s
      // faster at the reading's speed. Either row taking the other's speeds leaves a residual.
      const WheelSpeedMeasurement span = SpeedsOf(v + 3.0, w, gyro, truth, f);
      const WheelSpeedMeasurement instant = SpeedsOf(v, w + 0.2, gyro, truth, f);
      wheel_speeds.yaw_row_m_s = Eigen::Vector2d(span.left_m_s, span.right_m_s);
      wheel_speeds.left_m_s = instant.left_m_s;
      wheel_speeds.right_m_s = instant.right_m_s;
    }
    const std::unique_ptr<ceres::CostFunction> speeds(
        WheelSpeedResidual::Create(wheel_speeds, options));
    const std::unique_ptr<ceres::CostFunction> twist(
        OdometryTwistResidual::Create(TwistOf(v, w, gyro, f), options));
    const std::string context = "trial " + std::to_string(trial);
    const test::Evaluation at_speeds = test::Evaluate(*speeds, SpeedBlocks(&state, &f));
    const test::Evaluation at_twist = test::Evaluate(*twist, TwistBlocks(&state, &f));
    ASSERT_EQ(at_speeds.residual.size(), options.non_holonomic ? 4 : 2);
    EXPECT_LT(at_speeds.residual.norm(), 1e-9) << context << ": " << at_speeds.residual.transpose();
    EXPECT_LT(at_twist.residual.norm(), 1e-9) << context << ": " << at_twist.residual.transpose();
    if (yaw_axis) {
      // About the measured axis the yaw row does not depend on the mount's tilt: tilted by
      // 0.1 rad, the mount leaves it at zero (about V's z it would read cos(0.1) of the rate).
      const Eigen::Quaterniond saved = state.q_I_V;
      state.q_I_V = saved * geometry::Exp(Eigen::Vector3d(0.1, 0.0, 0.0));
      EXPECT_LT(std::abs(test::Evaluate(*speeds, SpeedBlocks(&state, &f)).residual(1)), 1e-9)
          << context;
      EXPECT_LT(std::abs(test::Evaluate(*twist, TwistBlocks(&state, &f)).residual(1)), 1e-9)
          << context;
      state.q_I_V = saved;
    }
    // A 1 % error in an intrinsic shows: each block enters the prediction.
    for (double* block : {&f.scale_left, &f.scale_right, &state.track_width}) {
      const double saved = *block;
      *block *= 1.01;
      EXPECT_GT(test::Evaluate(*speeds, SpeedBlocks(&state, &f)).residual.norm(), 1e-3) << context;
      *block = saved;
    }
    for (double* block : {&f.speed_scale, &f.effective_track_m}) {
      const double saved = *block;
      *block *= 1.01;
      EXPECT_GT(test::Evaluate(*twist, TwistBlocks(&state, &f)).residual.norm(), 1e-3) << context;
      *block = saved;
    }
  }
}

TEST(WheelForms, JacobiansPassGradientChecker) {
  const geometry::RightQuaternionManifold quaternion;
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    WheelBlocks state = RandomCalibration(&rng);
    FormIntrinsics f = RandomIntrinsics(&rng);
    state.q_W_I = Eigen::Quaterniond::UnitRandom();
    state.v_W_I = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 15.0;
    const Eigen::Vector3d gyro(u(rng), u(rng), u(rng));
    WheelFactorOptions options;
    options.non_holonomic = trial % 2 == 0;
    options.lateral_sigma_m_s = 0.03;
    options.vertical_sigma_m_s = 0.11;
    options.yaw_rate_sigma_rad_s = 0.013;
    const std::string context = "trial " + std::to_string(trial);
    // Random measurements, far from agreeing with the state: every Jacobian term counts.
    const std::unique_ptr<ceres::CostFunction> speeds(
        WheelSpeedResidual::Create(SpeedsOf(12.0 * u(rng), 0.7 * u(rng), gyro, state, f), options));
    const std::unique_ptr<ceres::CostFunction> twist(
        OdometryTwistResidual::Create(TwistOf(1.5 * u(rng), 1.2 * u(rng), gyro, f), options));
    std::vector<const ceres::Manifold*> manifolds = {&quaternion, nullptr, nullptr, &quaternion,
                                                     nullptr,     nullptr, nullptr, nullptr};
    test::ExpectGradientCheckPasses(*speeds, manifolds, SpeedBlocks(&state, &f), 1e-6,
                                    context + " speeds");
    manifolds.pop_back();
    test::ExpectGradientCheckPasses(*twist, manifolds, TwistBlocks(&state, &f), 1e-6,
                                    context + " twist");
  }
}

// The twist's rows in closed form, k_v and b_eff as the derivation states them (Eq. F26):
// a car at rest with zero gyro, the residual is the scaled measurement itself.
TEST(WheelForms, TwistRowsScaleSpeedByKvAndYawRateByControllerOverEffectiveTrack) {
  OdometryMeasurement m;
  m.speed_m_s = 0.8;
  m.yaw_rate_rad_s = 0.5;
  m.controller_track_m = 0.555;
  WheelFactorOptions options;
  options.non_holonomic = false;
  options.speed_sigma_m_s = 0.1;
  options.yaw_rate_sigma_rad_s = 0.2;
  const std::unique_ptr<ceres::CostFunction> twist(OdometryTwistResidual::Create(m, options));
  WheelBlocks state;
  FormIntrinsics f;
  f.speed_scale = 0.96;
  f.effective_track_m = 0.9;
  const test::Evaluation e = test::Evaluate(*twist, TwistBlocks(&state, &f));
  EXPECT_NEAR(e.residual(0), -0.96 * 0.8 / 0.1, 1e-12);
  EXPECT_NEAR(e.residual(1), -0.96 * 0.5 * 0.555 / 0.9 / 0.2, 1e-12);
}

TEST(WheelForms, RejectBadInputAndInvalidTracks) {
  WheelSpeedMeasurement speeds;
  speeds.left_m_s = std::nan("");
  EXPECT_THROW(WheelSpeedResidual::Create(speeds, WheelFactorOptions{}), Error);
  OdometryMeasurement twist;
  twist.controller_track_m = 0.0;
  EXPECT_THROW(OdometryTwistResidual::Create(twist, WheelFactorOptions{}), Error);
  twist.controller_track_m = 0.5;
  twist.yaw_rate_rad_s = std::numeric_limits<double>::infinity();
  EXPECT_THROW(OdometryTwistResidual::Create(twist, WheelFactorOptions{}), Error);
  WheelFactorOptions bad;
  bad.yaw_rate_sigma_rad_s = -1.0;
  EXPECT_THROW(OdometryTwistResidual::Create(OdometryMeasurement{}, bad), Error);
  // A non-positive track is an invalid step, not a NaN.
  const std::unique_ptr<ceres::CostFunction> cost(
      OdometryTwistResidual::Create(OdometryMeasurement{}, WheelFactorOptions{}));
  WheelBlocks state;
  FormIntrinsics f;
  f.effective_track_m = 0.0;
  const std::vector<double*> blocks = TwistBlocks(&state, &f);
  Eigen::Vector4d residual;
  EXPECT_FALSE(cost->Evaluate(blocks.data(), residual.data(), nullptr));
  // Sigmas from the stated noise: sqrt(2) s / b on the yaw rate of two wheel speeds.
  sensors::WheelConfig config;
  config.noise_m_s = 0.05;
  const WheelFactorOptions from_speeds = WheelFactorOptions::FromWheelSpeedNoise(config, 1.5);
  EXPECT_DOUBLE_EQ(from_speeds.speed_sigma_m_s, 0.05 / std::sqrt(2.0));
  EXPECT_DOUBLE_EQ(from_speeds.yaw_rate_sigma_rad_s, std::sqrt(2.0) * 0.05 / 1.5);
  config.yaw_rate_noise_rad_s = 0.03;
  EXPECT_EQ(WheelFactorOptions::FromOdometryNoise(config).yaw_rate_sigma_rad_s, 0.03);
}

}  // namespace
}  // namespace factors
}  // namespace autocal
