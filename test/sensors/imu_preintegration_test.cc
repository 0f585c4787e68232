#include "autocal/sensors/imu_preintegration.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <memory>
#include <random>
#include <sstream>
#include <string>

#include "autocal/common/error.h"
#include "autocal/geometry/so3.h"
#include "sensors/imu_test_trajectory.h"

namespace autocal {
namespace sensors {
namespace {

using test::ConstantTwistTrajectory;
using test::ImuTrajectory;
using test::SmoothTrajectory;

const Eigen::Vector3d kGravity(0.0, 0.0, -9.80665);

struct DeltaErrors {
  double rotation_rad;
  double velocity_m_s;
  double position_m;
};

std::unique_ptr<ImuTrajectory> MakeTrajectory(const std::string& name) {
  if (name == "constant_twist") {
    const geometry::Pose3d T0(geometry::Exp(Eigen::Vector3d(0.3, -0.8, 2.0)),
                              Eigen::Vector3d(5.0, -3.0, 1.0));
    return std::make_unique<ConstantTwistTrajectory>(T0, Eigen::Vector3d(8.0, 0.5, -0.2),
                                                     Eigen::Vector3d(0.2, -0.4, 1.1));
  }
  if (name == "accelerating") {
    SmoothTrajectory::Curve position, rotation;
    position.c1 = Eigen::Vector3d(3.0, 1.0, 0.0);
    position.c2 = Eigen::Vector3d(1.5, -0.7, 0.2);
    rotation.c0 = Eigen::Vector3d(0.1, 0.2, 2.5);
    rotation.c1 = Eigen::Vector3d(0.0, 0.1, 0.4);
    rotation.c2 = Eigen::Vector3d(0.3, -0.2, 0.6);
    return std::make_unique<SmoothTrajectory>(position, rotation);
  }
  return std::make_unique<SmoothTrajectory>(SmoothTrajectory::Random(7));
}

// Preintegrates the trajectory's exact samples at the given period over [t_i_ns, t_j_ns]
// and compares with the closed-form deltas.
DeltaErrors IntegrationError(const ImuTrajectory& trajectory, int64_t period_ns, int64_t t_i_ns,
                             int64_t t_j_ns) {
  const int count = static_cast<int>(t_j_ns / period_ns) + 2;
  const ImuSamples samples = test::SampleImu(trajectory, 0, period_ns, count, kGravity);
  ImuPreintegration pim{ImuNoise(), PreintegrationOptions()};
  pim.Integrate(samples, t_i_ns, t_j_ns);
  const test::TrueDeltas truth =
      test::ExactDeltas(trajectory, NsToSeconds(t_i_ns), NsToSeconds(t_j_ns), kGravity);
  return {geometry::AngularDistance(pim.delta_q(), truth.dq), (pim.delta_v() - truth.dv).norm(),
          (pim.delta_p() - truth.dp).norm()};
}

class PreintegrationAccuracy : public ::testing::TestWithParam<std::string> {};

// The midpoint scheme (Eq. F3) is second order: halving the sample period divides the error
// by ~4. Keyframe times fall between samples, so boundary splitting is part of the test.
TEST_P(PreintegrationAccuracy, ErrorShrinksWithSecondOrderInSamplePeriod) {
  const std::unique_ptr<ImuTrajectory> trajectory = MakeTrajectory(GetParam());
  const int64_t t_i_ns = 12'345'678;
  const int64_t t_j_ns = 1'012'345'678;
  const int64_t periods_ns[] = {10'000'000, 5'000'000, 2'500'000, 1'250'000};
  DeltaErrors previous{};
  for (int level = 0; level < 4; ++level) {
    const DeltaErrors e = IntegrationError(*trajectory, periods_ns[level], t_i_ns, t_j_ns);
    SCOPED_TRACE(GetParam() + ", period " + std::to_string(periods_ns[level]) + " ns");
    // Absolute accuracy at 200 Hz and above: well inside what the factors need.
    if (level >= 1) {
      EXPECT_LT(e.rotation_rad, 1e-5);
      EXPECT_LT(e.velocity_m_s, 1e-4);
      EXPECT_LT(e.position_m, 1e-4);
    }
    if (level > 0) {
      const double errors[3][2] = {{previous.rotation_rad, e.rotation_rad},
                                   {previous.velocity_m_s, e.velocity_m_s},
                                   {previous.position_m, e.position_m}};
      const char* names[3] = {"rotation", "velocity", "position"};
      for (int c = 0; c < 3; ++c) {
        if (errors[c][0] < 1e-11) continue;  // exact up to rounding (e.g. constant rate)
        const double ratio = errors[c][0] / errors[c][1];
        EXPECT_GT(ratio, 3.2) << names[c] << " error " << errors[c][0] << " -> " << errors[c][1];
        EXPECT_LT(ratio, 4.8) << names[c] << " error " << errors[c][0] << " -> " << errors[c][1];
      }
    }
    previous = e;
  }
}

INSTANTIATE_TEST_SUITE_P(Trajectories, PreintegrationAccuracy,
                         ::testing::Values("constant_twist", "accelerating", "random_smooth"));

// Two adjacent intervals split at a time between samples compose to the whole motion, and
// the covered time is exact (no sample dropped or counted twice). Splitting a step changes
// the discretization only locally (third order), so the composition is as accurate as the
// whole-interval integration.
TEST(ImuPreintegration, AdjacentIntervalsComposeToTheWhole) {
  const SmoothTrajectory trajectory = SmoothTrajectory::Random(21);
  const ImuSamples samples = test::SampleImu(trajectory, 0, 5'000'000, 300, kGravity);
  const int64_t t_a = 3'100'000, t_m = 402'700'001, t_b = 903'300'000;
  ImuPreintegration first{ImuNoise(), PreintegrationOptions()};
  ImuPreintegration second{ImuNoise(), PreintegrationOptions()};
  ImuPreintegration whole{ImuNoise(), PreintegrationOptions()};
  first.Integrate(samples, t_a, t_m);
  second.Integrate(samples, t_m, t_b);
  whole.Integrate(samples, t_a, t_b);
  EXPECT_NEAR(first.dt_s() + second.dt_s(), SecondsBetween(t_a, t_b), 1e-12);
  EXPECT_NEAR(whole.dt_s(), SecondsBetween(t_a, t_b), 1e-12);
  const Eigen::Quaterniond dq = first.delta_q() * second.delta_q();
  const Eigen::Vector3d dv = first.delta_v() + first.delta_q() * second.delta_v();
  const Eigen::Vector3d dp =
      first.delta_p() + first.delta_v() * second.dt_s() + first.delta_q() * second.delta_p();
  const test::TrueDeltas truth =
      test::ExactDeltas(trajectory, NsToSeconds(t_a), NsToSeconds(t_b), kGravity);
  const double whole_errors[3] = {geometry::AngularDistance(whole.delta_q(), truth.dq),
                                  (whole.delta_v() - truth.dv).norm(),
                                  (whole.delta_p() - truth.dp).norm()};
  const double split_errors[3] = {geometry::AngularDistance(dq, truth.dq), (dv - truth.dv).norm(),
                                  (dp - truth.dp).norm()};
  const double split_vs_whole[3] = {geometry::AngularDistance(dq, whole.delta_q()),
                                    (dv - whole.delta_v()).norm(), (dp - whole.delta_p()).norm()};
  for (int c = 0; c < 3; ++c) {
    EXPECT_LT(split_vs_whole[c], 0.05 * whole_errors[c])
        << "component " << c << ": split " << split_errors[c] << ", whole " << whole_errors[c];
  }
}

// The propagation helper (Eq. F8) lands on the trajectory, with biases removed.
TEST(ImuPreintegration, PredictPropagatesKeyframeState) {
  const SmoothTrajectory trajectory = SmoothTrajectory::Random(3);
  const Eigen::Vector3d b_g(0.01, -0.02, 0.015), b_a(0.1, 0.05, -0.2);
  const ImuSamples samples = test::SampleImu(trajectory, 0, 2'500'000, 400, kGravity, b_g, b_a);
  for (const int64_t t_ns : {37'000'000, 250'000'000, 811'111'111}) {
    const int64_t t_k_ns = 20'000'000;
    ImuPreintegration pim(ImuNoise(), PreintegrationOptions(), b_g, b_a);
    pim.Integrate(samples, t_k_ns, t_ns);
    const NavStated predicted = pim.Predict(trajectory.State(NsToSeconds(t_k_ns)), b_g, b_a);
    const NavStated truth = trajectory.State(NsToSeconds(t_ns));
    SCOPED_TRACE("t = " + std::to_string(t_ns) + " ns");
    EXPECT_LT(geometry::AngularDistance(predicted.q_W_I, truth.q_W_I), 1e-5);
    EXPECT_LT((predicted.v_W_I - truth.v_W_I).norm(), 1e-4)
        << predicted.v_W_I.transpose() << " vs " << truth.v_W_I.transpose();
    EXPECT_LT((predicted.p_W_I - truth.p_W_I).norm(), 1e-4)
        << predicted.p_W_I.transpose() << " vs " << truth.p_W_I.transpose();
  }
}

// Eq. F7: the first-order bias correction matches a full re-integration with an error
// quadratic in the bias change.
TEST(ImuPreintegration, BiasCorrectionErrorIsQuadraticInTheChange) {
  const SmoothTrajectory trajectory = SmoothTrajectory::Random(5, 2.0, 1.0);
  const ImuSamples samples = test::SampleImu(trajectory, 0, 5'000'000, 250, kGravity);
  const Eigen::Vector3d dir_g = Eigen::Vector3d(0.6, -0.3, 0.74).normalized();
  const Eigen::Vector3d dir_a = Eigen::Vector3d(-0.2, 0.9, 0.4).normalized();
  ImuPreintegration linearized{ImuNoise(), PreintegrationOptions()};
  linearized.Integrate(samples, 0, 1'000'000'000);
  double previous[3] = {0.0, 0.0, 0.0};
  for (int level = 0; level < 4; ++level) {
    const double scale = std::ldexp(1.0, -level);
    const Eigen::Vector3d b_g = 0.02 * scale * dir_g;
    const Eigen::Vector3d b_a = 0.2 * scale * dir_a;
    ImuPreintegration exact = linearized;
    exact.Reintegrate(b_g, b_a);
    Eigen::Quaterniond dq;
    Eigen::Vector3d dv, dp;
    linearized.Corrected(b_g, b_a, &dq, &dv, &dp);
    const double errors[3] = {geometry::AngularDistance(dq, exact.delta_q()),
                              (dv - exact.delta_v()).norm(), (dp - exact.delta_p()).norm()};
    const double uncorrected_v = (linearized.delta_v() - exact.delta_v()).norm();
    SCOPED_TRACE("bias change scale " + std::to_string(scale));
    EXPECT_LT(errors[1], 0.05 * uncorrected_v)
        << "correction does not help: " << errors[1] << " vs uncorrected " << uncorrected_v;
    if (level > 0) {
      for (int c = 0; c < 3; ++c) {
        const double ratio = previous[c] / errors[c];
        EXPECT_GT(ratio, 3.5) << "component " << c << ": " << previous[c] << " -> " << errors[c];
        EXPECT_LT(ratio, 4.5) << "component " << c << ": " << previous[c] << " -> " << errors[c];
      }
    }
    std::copy(errors, errors + 3, previous);
  }
}

TEST(ImuPreintegration, ReintegratesOnlyBeyondThreshold) {
  const SmoothTrajectory trajectory = SmoothTrajectory::Random(9);
  const ImuSamples samples = test::SampleImu(trajectory, 0, 5'000'000, 60, kGravity);
  PreintegrationOptions options;
  ImuPreintegration pim(ImuNoise(), options);
  pim.Integrate(samples, 0, 250'000'000);
  const Eigen::Vector3d small_g =
      Eigen::Vector3d::Constant(0.5 * options.reintegrate_gyro_bias_rad_s);
  EXPECT_FALSE(pim.ReintegrateIfNeeded(small_g, Eigen::Vector3d::Zero()));
  EXPECT_EQ(pim.b_g_lin(), Eigen::Vector3d::Zero());
  const Eigen::Vector3d large_a(0.0, 2.0 * options.reintegrate_accel_bias_m_s2, 0.0);
  EXPECT_TRUE(pim.ReintegrateIfNeeded(small_g, large_a));
  EXPECT_EQ(pim.b_g_lin(), small_g);
  EXPECT_EQ(pim.b_a_lin(), large_a);
  ImuPreintegration direct(ImuNoise(), options, small_g, large_a);
  direct.Integrate(samples, 0, 250'000'000);
  EXPECT_LT((pim.delta_v() - direct.delta_v()).norm(), 1e-14);
  EXPECT_LT((pim.Covariance() - direct.Covariance()).norm(), 1e-14 * direct.Covariance().norm());
}

// Monte-Carlo: white measurement noise of density sigma sampled at rate 1/dt has per-sample
// standard deviation sigma / sqrt(dt); the bias follows a random walk. The sample covariance
// of the preintegration errors must match Covariance() (Eq. F4, F5).
TEST(ImuPreintegration, CovarianceMatchesMonteCarlo) {
  const SmoothTrajectory trajectory = SmoothTrajectory::Random(13, 2.0, 1.0);
  constexpr int64_t kPeriodNs = 5'000'000;
  constexpr int kSamples = 101;  // 0.5 s at 200 Hz
  constexpr int kDraws = 3000;
  const double dt = NsToSeconds(kPeriodNs);
  ImuNoise noise;
  // Larger than a MEMS unit's so that the bias drift matters within 0.5 s.
  noise.gyroscope_random_walk = 2e-3;
  noise.accelerometer_random_walk = 2e-2;
  const ImuSamples clean = test::SampleImu(trajectory, 0, kPeriodNs, kSamples, kGravity);
  const int64_t t_end = (kSamples - 1) * kPeriodNs;
  ImuPreintegration nominal(noise, PreintegrationOptions());
  nominal.Integrate(clean, 0, t_end);
  const Matrix15d cov = nominal.Covariance();
  const Matrix15d info = cov.inverse();

  std::mt19937 rng(2024);
  std::normal_distribution<double> n01(0.0, 1.0);
  auto gauss = [&]() { return Eigen::Vector3d(n01(rng), n01(rng), n01(rng)); };
  Matrix15d sample_cov = Matrix15d::Zero();
  double chi2_sum = 0.0;
  for (int draw = 0; draw < kDraws; ++draw) {
    Eigen::Vector3d b_g, b_a;
    const ImuSamples noisy = test::NoisyDraw(clean, dt, noise, gauss, &b_g, &b_a);
    PreintegrationOptions fast;
    fast.compute_covariance = false;
    ImuPreintegration pim(noise, fast);
    pim.Integrate(noisy, 0, t_end);
    Eigen::Matrix<double, 15, 1> e;
    e << geometry::Log(Eigen::Quaterniond(nominal.delta_q().conjugate() * pim.delta_q())),
        pim.delta_v() - nominal.delta_v(), pim.delta_p() - nominal.delta_p(), b_g, b_a;
    sample_cov += e * e.transpose() / kDraws;
    chi2_sum += e.dot(info * e);
  }
  for (int i = 0; i < 15; ++i) {
    EXPECT_NEAR(sample_cov(i, i) / cov(i, i), 1.0, 0.1)
        << "component " << i << ": Monte-Carlo " << sample_cov(i, i) << ", propagated "
        << cov(i, i);
  }
  // Mean of e^T P^-1 e is 15 with standard error sqrt(2 * 15 / kDraws) ~ 0.07: a check of
  // the correlations too.
  const double chi2_mean = chi2_sum / kDraws;
  EXPECT_NEAR(chi2_mean, 15.0, 0.6) << "mean normalized squared error";
}

// Eq. F5b: a step across a dropout (samples farther apart than max_sample_interval_s) adds the
// unknown signal's variance for the whole step: on the rotation, D^2 sigma_g^2 per axis for a
// dropout of D (the right Jacobian of the step's rotation, up to 0.3 rad here, moves it by a
// few percent). A regular stream integrates bit for bit as without the setting.
TEST(ImuPreintegration, ADropoutAddsTheUnknownSignalsVariance) {
  const SmoothTrajectory trajectory = SmoothTrajectory::Random(13, 2.0, 1.0);
  constexpr int64_t kPeriodNs = 5'000'000;
  const ImuSamples regular = test::SampleImu(trajectory, 0, kPeriodNs, 201, kGravity);  // 1 s
  ImuSamples dropout;
  for (const ImuSample& sample : regular) {
    if (sample.t_ns <= 400'000'000 || sample.t_ns >= 700'000'000) dropout.push_back(sample);
  }
  ImuNoise plain;
  ImuNoise with_dropouts = plain;
  with_dropouts.max_sample_interval_s = 0.0125;
  with_dropouts.dropout_gyro_sigma_rad_s = 0.05;
  with_dropouts.dropout_accel_sigma_m_s2 = 0.5;
  const auto covariance = [](const ImuNoise& noise, const ImuSamples& samples) {
    ImuPreintegration pim(noise, PreintegrationOptions());
    pim.Integrate(samples, 0, 1'000'000'000);
    return pim.Covariance();
  };
  EXPECT_EQ(covariance(with_dropouts, regular), covariance(plain, regular));
  const Matrix15d added = covariance(with_dropouts, dropout) - covariance(plain, dropout);
  const double expected = 0.3 * 0.3 * 0.05 * 0.05;
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(added(i, i), expected, 0.03 * expected) << i;
    for (int j = 0; j < 3; ++j) {
      if (j != i) {
        EXPECT_NEAR(added(i, j), 0.0, 0.03 * expected) << i << ", " << j;
      }
    }
  }
  // The velocity (rows 3-5) by at least the specific force's own share, D^2 sigma_a^2; the
  // position (rows 6-8) by at least its D^2 / 2 in the step and D T over the T = 0.3 s after it
  // (the rotation's share, through the specific force, comes on top).
  for (int i = 3; i < 6; ++i) EXPECT_GT(added(i, i), 0.3 * 0.3 * 0.5 * 0.5) << i;
  const double position_share = 0.5 * 0.5 * std::pow(0.5 * 0.3 * 0.3 + 0.3 * 0.3, 2);
  for (int i = 6; i < 9; ++i) EXPECT_GT(added(i, i), 0.95 * position_share) << i;
  // The biases' blocks are the random walk's alone.
  EXPECT_TRUE((added.bottomRightCorner<6, 6>().isZero(0.0)));
}

TEST(ImuPreintegration, SqrtInformationWhitensTheCovariance) {
  const SmoothTrajectory trajectory = SmoothTrajectory::Random(17);
  const ImuSamples samples = test::SampleImu(trajectory, 0, 5'000'000, 60, kGravity);
  ImuPreintegration pim{ImuNoise(), PreintegrationOptions()};
  pim.Integrate(samples, 1'000'000, 251'000'000);
  const Matrix15d U = pim.SqrtInformation();
  const Matrix15d whitened = U * pim.Covariance() * U.transpose();
  EXPECT_LT((whitened - Matrix15d::Identity()).norm(), 1e-8) << whitened;
  EXPECT_TRUE(U.isLowerTriangular());
}

// Dense reference of Eq. F3-F6: the 15x15 transition A and the 15x12 input matrix of one
// step formed explicitly, P <- A P A^T + G Q G^T, then rotated to the right error.
struct DenseReference {
  Eigen::Quaterniond dq = Eigen::Quaterniond::Identity();
  Eigen::Vector3d dv = Eigen::Vector3d::Zero();
  Eigen::Vector3d dp = Eigen::Vector3d::Zero();
  Matrix15d P = Matrix15d::Zero();
  Eigen::Matrix3d K_theta_g = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d v_bg = Eigen::Matrix3d::Zero(), v_ba = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d p_bg = Eigen::Matrix3d::Zero(), p_ba = Eigen::Matrix3d::Zero();

  void Step(const ImuNoise& noise, const Eigen::Vector3d& omega, const Eigen::Vector3d& accel,
            double dt) {
    using geometry::Hat;
    const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
    const Eigen::Matrix3d R_k = dq.toRotationMatrix();
    const Eigen::Quaterniond q_half = geometry::Exp(Eigen::Vector3d(0.5 * dt * omega));
    const Eigen::Matrix3d R_mid = (dq * q_half).toRotationMatrix();
    const Eigen::Vector3d u = R_mid * accel * dt;
    const Eigen::Matrix3d S = Hat(u);
    const Eigen::Matrix3d G_theta = R_k * geometry::LeftJacobian(Eigen::Vector3d(omega * dt)) * dt;
    const Eigen::Matrix3d G_half =
        R_k * geometry::LeftJacobian(Eigen::Vector3d(0.5 * dt * omega)) * (0.5 * dt);
    const Eigen::Matrix3d G_vg = -S * G_half;
    const Eigen::Matrix3d G_va = R_mid * dt;

    Matrix15d A = Matrix15d::Identity();
    A.block<3, 3>(3, 0) = -S;
    A.block<3, 3>(6, 0) = -0.5 * dt * S;
    A.block<3, 3>(6, 3) = dt * I;
    Eigen::Matrix<double, 15, 12> G = Eigen::Matrix<double, 15, 12>::Zero();
    G.block<3, 3>(0, 0) = G_theta;
    G.block<3, 3>(3, 0) = G_vg;
    G.block<3, 3>(3, 3) = G_va;
    G.block<3, 6>(6, 0) = 0.5 * dt * G.block<3, 6>(3, 0);
    G.block<6, 6>(9, 6).setIdentity();
    // A bias error enters the deltas as the measurement noise does.
    A.block<9, 6>(0, 9) = G.block<9, 6>(0, 0);
    Eigen::Matrix<double, 12, 1> q;
    q << Eigen::Vector3d::Constant(std::pow(noise.gyroscope_noise_density, 2) / dt),
        Eigen::Vector3d::Constant(std::pow(noise.accelerometer_noise_density, 2) / dt),
        Eigen::Vector3d::Constant(std::pow(noise.gyroscope_random_walk, 2) * dt),
        Eigen::Vector3d::Constant(std::pow(noise.accelerometer_random_walk, 2) * dt);
    P = A * P * A.transpose() + G * q.asDiagonal() * G.transpose();

    const Eigen::Matrix3d v_bg_step = -S * (K_theta_g - G_half);
    p_bg += dt * v_bg + 0.5 * dt * v_bg_step;
    p_ba += dt * v_ba - 0.5 * dt * G_va;
    v_bg += v_bg_step;
    v_ba -= G_va;
    K_theta_g -= G_theta;

    dp += dt * dv + 0.5 * dt * u;
    dv += u;
    dq = (dq * q_half * q_half).normalized();
  }

  Matrix15d Covariance() const {
    Matrix15d T = Matrix15d::Identity();
    T.topLeftCorner<3, 3>() = dq.conjugate().toRotationMatrix();
    return T * P * T.transpose();
  }
};

// Largest |a_ij - b_ij| / sqrt(b_ii b_jj): the difference on the scale of the standard
// deviations, so that near-zero correlations do not count as large relative errors.
double MaxNormalizedDifference(const Matrix15d& a, const Matrix15d& b) {
  double worst = 0.0;
  for (int i = 0; i < 15; ++i) {
    for (int j = 0; j < 15; ++j) {
      worst = std::max(worst, std::abs(a(i, j) - b(i, j)) / std::sqrt(b(i, i) * b(j, j)));
    }
  }
  return worst;
}

double RelativeDifference(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return (a - b).lpNorm<Eigen::Infinity>() / b.lpNorm<Eigen::Infinity>();
}

// The block-structured propagation (Eq. F4-F6) equals the dense products to rounding, on
// random steps: rates up to ~6 rad/s and step lengths up to 60 ms, so both the small-angle
// series and the closed forms of Exp and Jl are used, random biases and noise densities.
TEST(ImuPreintegration, BlockPropagationMatchesDenseReference) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  auto random_vector = [&](double scale) -> Eigen::Vector3d {
    Eigen::Vector3d v;
    for (int i = 0; i < 3; ++i) v(i) = scale * uniform(rng);
    return v;
  };
  auto random_positive = [&](double low, double high) {
    return low + 0.5 * (uniform(rng) + 1.0) * (high - low);
  };
  double worst_covariance = 0.0, worst_jacobian = 0.0;
  for (int trial = 0; trial < 6; ++trial) {
    ImuNoise noise;
    noise.gyroscope_noise_density = random_positive(1e-4, 1e-2);
    noise.gyroscope_random_walk = random_positive(1e-5, 1e-2);
    noise.accelerometer_noise_density = random_positive(1e-3, 1e-1);
    noise.accelerometer_random_walk = random_positive(1e-3, 1e-1);
    const Eigen::Vector3d b_g = random_vector(0.05), b_a = random_vector(0.5);
    ImuPreintegration pim(noise, PreintegrationOptions(), b_g, b_a);
    DenseReference reference;
    const int steps = 20 + 40 * trial;
    for (int k = 0; k < steps; ++k) {
      const bool large = k % 7 == 3;
      const Eigen::Vector3d gyro = random_vector(large ? 6.0 : 1.5);
      const Eigen::Vector3d accel = random_vector(12.0);
      const double dt = large ? random_positive(0.02, 0.06) : random_positive(1e-3, 1e-2);
      pim.IntegrateStep(gyro, accel, dt);
      reference.Step(noise, gyro - b_g, accel - b_a, dt);
    }
    SCOPED_TRACE("trial " + std::to_string(trial));
    ASSERT_LT((pim.delta_v() - reference.dv).norm(), 1e-12 * reference.dv.norm());
    worst_covariance = std::max(worst_covariance,
                                MaxNormalizedDifference(pim.Covariance(), reference.Covariance()));
    const Eigen::Matrix3d d_R_d_bg =
        reference.dq.conjugate().toRotationMatrix() * reference.K_theta_g;
    const double jacobian_errors[] = {RelativeDifference(pim.d_R_d_bg(), d_R_d_bg),
                                      RelativeDifference(pim.d_v_d_bg(), reference.v_bg),
                                      RelativeDifference(pim.d_v_d_ba(), reference.v_ba),
                                      RelativeDifference(pim.d_p_d_bg(), reference.p_bg),
                                      RelativeDifference(pim.d_p_d_ba(), reference.p_ba)};
    for (double e : jacobian_errors) worst_jacobian = std::max(worst_jacobian, e);
  }
  EXPECT_LT(worst_covariance, 1e-12);
  EXPECT_LT(worst_jacobian, 1e-12);
  std::ostringstream differences;
  differences << std::scientific << std::setprecision(2) << "covariance " << worst_covariance
              << ", bias Jacobians " << worst_jacobian;
  RecordProperty("largest_differences", differences.str());
}

TEST(ImuPreintegration, RejectsBadInput) {
  const SmoothTrajectory trajectory = SmoothTrajectory::Random(1);
  ImuSamples samples = test::SampleImu(trajectory, 1'000'000, 5'000'000, 20, kGravity);
  ImuPreintegration pim{ImuNoise(), PreintegrationOptions()};
  auto expect_error = [&](const ImuSamples& s, int64_t a, int64_t b, const std::string& text) {
    try {
      pim.Integrate(s, a, b);
      ADD_FAILURE() << "no error for interval [" << a << ", " << b << "]";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
    }
  };
  expect_error(samples, 0, 50'000'000, "do not cover");
  expect_error(samples, 10'000'000, 200'000'000, "do not cover");
  expect_error(samples, 50'000'000, 10'000'000, "before it starts");
  ImuSamples unsorted = samples;
  std::swap(unsorted[5].t_ns, unsorted[6].t_ns);
  expect_error(unsorted, 2'000'000, 90'000'000, "does not increase");
  ImuSamples nan = samples;
  nan[7].accel_m_s2.y() = std::nan("");
  expect_error(nan, 2'000'000, 90'000'000, "not finite");
  ImuNoise negative;
  negative.gyroscope_noise_density = -1.0;
  EXPECT_THROW(ImuPreintegration(negative, PreintegrationOptions{}), Error);
  EXPECT_THROW(ImuPreintegration(ImuNoise(), PreintegrationOptions{}).SqrtInformation(), Error);
}

TEST(InterpolateImu, IsLinearBetweenSamples) {
  ImuSamples samples(2);
  samples[0].t_ns = 100;
  samples[1].t_ns = 300;
  samples[1].gyro_rad_s = Eigen::Vector3d(2.0, -4.0, 6.0);
  samples[1].accel_m_s2 = Eigen::Vector3d(1.0, 1.0, 1.0);
  const ImuSample mid = InterpolateImu(samples, 150);
  EXPECT_LT((mid.gyro_rad_s - 0.25 * samples[1].gyro_rad_s).norm(), 1e-15);
  EXPECT_LT((mid.accel_m_s2 - 0.25 * samples[1].accel_m_s2).norm(), 1e-15);
  EXPECT_THROW(InterpolateImu(samples, 301), Error);
  EXPECT_THROW(InterpolateImu(samples, 99), Error);
}

}  // namespace
}  // namespace sensors
}  // namespace autocal
