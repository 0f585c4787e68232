#include "autocal/estimation/keyframe_sensor_factors.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/planar_rotation_rows.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "autocal/sim/simulator.h"
#include "estimation/true_keyframe.h"
#include "support/simulation_cache.h"

namespace autocal {
namespace estimation {
namespace {

constexpr double kKeyframeSpacingS = 0.1;

using test::TrueKeyframe;

// True keyframes every 0.1 s, phase_s after the sample grid (IMU, wheel and GNSS stamps are
// multiples of their periods from the start), from 0.5 s to 0.5 s before the end.
std::vector<Keyframe> TrueKeyframes(const sim::Simulator& simulator, const sim::ImuLog& log,
                                    double phase_s) {
  std::vector<Keyframe> keyframes;
  for (double t_s = 0.5 + phase_s; t_s < simulator.options().duration_s - 0.5;
       t_s += kKeyframeSpacingS) {
    keyframes.push_back(TrueKeyframe(log, simulator.StampAt(t_s)));
  }
  return keyframes;
}

double PercentError(double estimate, double truth) { return 100.0 * (estimate - truth) / truth; }

// The options of a problem whose manifolds the test owns.
ceres::Problem::Options ManifoldsNotOwned() {
  ceres::Problem::Options options;
  options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return options;
}

// The keyframes' rotations in `problem` on `manifold` (quaternion blocks need their manifold
// before factors are attached).
void AddKeyframeRotations(std::vector<Keyframe>* keyframes, ceres::Manifold* manifold,
                          ceres::Problem* problem) {
  for (Keyframe& kf : *keyframes) problem->AddParameterBlock(kf.q_W_I.coeffs().data(), 4, manifold);
}

// An urban drive of 30 s (seed 7: straight driving, then the roundabout from 18 s, so the
// yaw rate is excited), LiDAR off; once with the simulator's noise, GNSS multipath outliers
// and outages, once without noise (outages stay); simulated once per test program and build
// (test/support/simulation_cache.h).
class KeyframeSensorFactorsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim::SimulationOptions options;
    options.scenario = sim::ScenarioType::kUrban;
    options.duration_s = 30.0;
    options.seed = 7;
    options.lidar.enabled = false;
    noisy_simulator_ = new sim::Simulator(options);
    noisy_ = new sim::SimulatedLog(test::CachedSimulatedLog(*noisy_simulator_));
    exact_simulator_ = new sim::Simulator(options.WithoutNoise());
    exact_ = new sim::SimulatedLog(test::CachedSimulatedLog(*exact_simulator_));
  }
  static void TearDownTestSuite() {
    delete exact_;
    delete exact_simulator_;
    delete noisy_;
    delete noisy_simulator_;
  }

  // W of the simulator is the ENU frame at its configured origin.
  static sensors::EnuConverter Converter(const sim::Simulator& simulator) {
    const sim::GnssSimOptions& gnss = simulator.options().gnss;
    return sensors::EnuConverter(gnss.origin_lat_deg, gnss.origin_lon_deg, gnss.origin_alt_m);
  }

  // A problem whose manifolds the fixture owns, with every keyframe block held at its value
  // and q_I_V added (quaternion blocks need their manifold before factors are attached).
  std::unique_ptr<ceres::Problem> ProblemWithConstantKeyframes(std::vector<Keyframe>* keyframes,
                                                               sensors::Calibration* calibration) {
    auto problem = std::make_unique<ceres::Problem>(ManifoldsNotOwned());
    for (Keyframe& kf : *keyframes) {
      problem->AddParameterBlock(kf.q_W_I.coeffs().data(), 4, &quaternion_manifold_);
      problem->SetParameterBlockConstant(kf.q_W_I.coeffs().data());
      for (double* block : {kf.p_W_I.data(), kf.v_W_I.data(), kf.b_g.data(), kf.b_a.data()}) {
        problem->AddParameterBlock(block, 3);
        problem->SetParameterBlockConstant(block);
      }
    }
    problem->AddParameterBlock(calibration->q_I_V.coeffs().data(), 4, &quaternion_manifold_);
    return problem;
  }

  static ceres::Solver::Summary Solve(ceres::Problem* problem) {
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::DENSE_QR;
    options.max_num_iterations = 50;
    options.function_tolerance = 1e-12;
    options.parameter_tolerance = 1e-12;
    ceres::Solver::Summary summary;
    ceres::Solve(options, problem, &summary);
    return summary;
  }

  // The lever arm estimated from the nominal guess with true, constant keyframes.
  Eigen::Vector3d LeverArmError(const factors::LossOptions& loss, int* added) {
    std::vector<Keyframe> keyframes = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
    sensors::Calibration calibration = noisy_simulator_->nominal_calibration();
    auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
    KeyframeGnssOptions options;
    options.loss = loss;
    *added = AddGnssFactors(problem.get(), noisy_->imu.samples, noisy_->gnss.fixes,
                            Converter(*noisy_simulator_), &keyframes, &calibration, options);
    const ceres::Solver::Summary summary = Solve(problem.get());
    EXPECT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
    return calibration.p_I_A - noisy_simulator_->true_calibration().p_I_A;
  }

  // The track, in mm from the truth, that the noise-free drive's wheel rows give with true
  // keyframes and radii, the mount q_I_V, the gyro's mean over gyro_span_s and the turning
  // axis's error limit (Eqs. K13b, K13c); the nominal track to start, every other block held.
  double TrackErrorMm(const Eigen::Quaterniond& q_I_V, const factors::WheelFactorOptions& rows,
                      double gyro_span_s, double max_axis_error_deg) {
    const sensors::Calibration& truth = exact_simulator_->true_calibration();
    std::vector<Keyframe> keyframes = TrueKeyframes(*exact_simulator_, exact_->imu, kPhaseS);
    sensors::Calibration calibration = truth;
    calibration.q_I_V = q_I_V;
    calibration.track_width_m = exact_simulator_->nominal_calibration().track_width_m;
    auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
    KeyframeWheelOptions options;
    options.factor = rows;
    options.estimate_vehicle_rotation = false;
    options.estimate_vehicle_translation = false;
    options.estimate_radii = false;
    options.gyro_mean_span_s = gyro_span_s;
    options.max_turning_axis_error_deg = max_axis_error_deg;
    EXPECT_GT(AddWheelFactors(problem.get(), exact_->imu.samples, exact_->wheel, &keyframes,
                              &calibration, options),
              0);
    const ceres::Solver::Summary summary = Solve(problem.get());
    EXPECT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
    return 1e3 * (calibration.track_width_m - truth.track_width_m);
  }

  // Keyframes off the sample grid (wheel every 10 ms, GNSS every 100 ms): every wheel
  // measurement is interpolated; each fix, which two neighbouring keyframes would share, serves
  // the nearer one (Eq. K17).
  static constexpr double kPhaseS = 0.037;

  static sim::Simulator* noisy_simulator_;
  static sim::SimulatedLog* noisy_;
  static sim::Simulator* exact_simulator_;
  static sim::SimulatedLog* exact_;
  geometry::RightQuaternionManifold quaternion_manifold_;
};

sim::Simulator* KeyframeSensorFactorsTest::noisy_simulator_ = nullptr;
sim::SimulatedLog* KeyframeSensorFactorsTest::noisy_ = nullptr;
sim::Simulator* KeyframeSensorFactorsTest::exact_simulator_ = nullptr;
sim::SimulatedLog* KeyframeSensorFactorsTest::exact_ = nullptr;

// One IMU factor per keyframe interval; on the noise-free log its whitened residual at the
// true states is small (integration error only), and a keyframe velocity 5 cm/s off shows.
TEST_F(KeyframeSensorFactorsTest, ImuFactorsBetweenConsecutiveKeyframes) {
  std::vector<Keyframe> keyframes = TrueKeyframes(*exact_simulator_, exact_->imu, kPhaseS);
  ceres::Problem problem(ManifoldsNotOwned());
  AddKeyframeRotations(&keyframes, &quaternion_manifold_, &problem);
  KeyframeImuOptions options;
  options.noise = exact_simulator_->sensors_config().imu.noise;
  options.gravity_m_s2 = exact_simulator_->options().imu.gravity_m_s2;
  options.num_threads = 2;
  EXPECT_EQ(AddImuFactors(&problem, exact_->imu.samples, &keyframes, options),
            static_cast<int>(keyframes.size()) - 1);
  const auto rms = [&]() {
    std::vector<double> residuals;
    problem.Evaluate(ceres::Problem::EvaluateOptions(), nullptr, &residuals, nullptr, nullptr);
    double sum = 0.0;
    for (double r : residuals) sum += r * r;
    return std::sqrt(sum / static_cast<double>(residuals.size()));
  };
  const double at_truth = rms();
  keyframes[keyframes.size() / 2].v_W_I.x() += 0.05;
  const double perturbed = rms();
  std::cout << "whitened IMU residual RMS " << at_truth << " at the truth, " << perturbed
            << " with one velocity 5 cm/s off\n";
  EXPECT_LT(at_truth, 0.1);
  EXPECT_GT(perturbed, 3.0 * at_truth);

  // Samples that do not cover the keyframes are refused.
  sensors::ImuSamples short_log(exact_->imu.samples.begin(),
                                exact_->imu.samples.begin() + exact_->imu.samples.size() / 2);
  ceres::Problem other(ManifoldsNotOwned());
  AddKeyframeRotations(&keyframes, &quaternion_manifold_, &other);
  EXPECT_THROW(AddImuFactors(&other, short_log, &keyframes, options), Error);
}

// Radii (separate) and track width from the nominal 0.33 m / 1.60 m (about 1 % off) with the
// true T_I_V and true keyframes held: the encoder noise (0.02 rad/s per wheel) averages out
// over the ~290 keyframes.
TEST_F(KeyframeSensorFactorsTest, WheelRadiiAndTrackWidthFromTheNominalGuess) {
  std::vector<Keyframe> keyframes = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
  const sensors::Calibration& truth = noisy_simulator_->true_calibration();
  sensors::Calibration calibration = noisy_simulator_->nominal_calibration();
  calibration.q_I_V = truth.q_I_V;
  calibration.p_I_V = truth.p_I_V;
  auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
  KeyframeWheelOptions options;
  options.factor = factors::WheelFactorOptions::FromEncoderNoise(
      noisy_simulator_->options().wheel.config, calibration.wheel_radius_left_m,
      calibration.track_width_m);
  options.estimate_vehicle_rotation = false;
  options.estimate_vehicle_translation = false;
  const int added = AddWheelFactors(problem.get(), noisy_->imu.samples, noisy_->wheel, &keyframes,
                                    &calibration, options);
  EXPECT_EQ(added, static_cast<int>(keyframes.size()));  // no wheel dropouts in the log
  const ceres::Solver::Summary summary = Solve(problem.get());
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();

  const double left_percent =
      PercentError(calibration.wheel_radius_left_m, truth.wheel_radius_left_m);
  const double right_percent =
      PercentError(calibration.wheel_radius_right_m, truth.wheel_radius_right_m);
  const double track_percent = PercentError(calibration.track_width_m, truth.track_width_m);
  std::cout << added << " wheel factors; radius error left " << left_percent << " %, right "
            << right_percent << " %, track width " << track_percent << " % (nominal was "
            << PercentError(noisy_simulator_->nominal_calibration().track_width_m,
                            truth.track_width_m)
            << " %)\n";
  // Measured: 0.011 %, -0.003 % and 0.039 %.
  EXPECT_LT(std::abs(left_percent), 0.05);
  EXPECT_LT(std::abs(right_percent), 0.05);
  EXPECT_LT(std::abs(track_percent), 0.2);
  // The held blocks did not move.
  EXPECT_EQ(calibration.p_I_V, truth.p_I_V);
}

// The yaw-rate row compares the gyro's mean over a span with the wheels' mean over the same
// span (Eq. K13b). On the noise-free drive with true keyframes and radii, the track from the
// roundabout's yaw rates is as exact with the gyro averaged over 0.2 s as with the instant's
// rate. Measured: -0.005 mm with the instant's, -0.05 mm over 0.2 s (the gyro's mean is of its
// samples, the wheels' of their lines); with the instant's wheel rates against the averaged gyro
// it came out 0.97 mm long (the mean attenuates the yaw rate's changes: errors in variables).
TEST_F(KeyframeSensorFactorsTest, TheYawRowAveragesTheWheelsOverTheGyrosSpan) {
  const sensors::Calibration& truth = exact_simulator_->true_calibration();
  const factors::WheelFactorOptions rows = factors::WheelFactorOptions::FromEncoderNoise(
      exact_simulator_->options().wheel.config, truth.wheel_radius_left_m, truth.track_width_m);
  for (double span_s : {0.0, 0.2}) {
    // About V's up axis, the true mount's.
    const double error_mm = TrackErrorMm(truth.q_I_V, rows, span_s, 0.0);
    std::cout << "gyro span " << span_s << " s: track " << error_mm << " mm off\n";
    EXPECT_LT(std::abs(error_mm), 0.1) << "gyro span " << span_s << " s";
  }
}

// Keyframes 0.1 s apart share half the wheel samples of their 0.2 s spans: each yaw-rate row
// weighs sqrt(2) less than with keyframes 0.2 s apart, so that a sample counts once (Eq. K13b).
// Compared on one keyframe through its row's derivative by the track.
TEST_F(KeyframeSensorFactorsTest, OverlappingSpansShareTheirSamplesWeight) {
  const sensors::Calibration& truth = noisy_simulator_->true_calibration();
  const std::vector<Keyframe> every = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
  double d_yaw_row_d_track[2] = {0.0, 0.0};
  for (int stride : {1, 2}) {
    std::vector<Keyframe> keyframes;
    for (size_t k = 0; k < every.size(); k += static_cast<size_t>(stride)) {
      keyframes.push_back(every[k]);
    }
    sensors::Calibration calibration = truth;
    auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
    KeyframeWheelOptions options;
    options.factor = factors::WheelFactorOptions::FromEncoderNoise(
        noisy_simulator_->options().wheel.config, truth.wheel_radius_left_m, truth.track_width_m);
    options.gyro_mean_span_s = 0.2;
    options.max_turning_axis_error_deg = 0.0;  // one axis for both sets of keyframes
    ASSERT_GT(AddWheelFactors(problem.get(), noisy_->imu.samples, noisy_->wheel, &keyframes,
                              &calibration, options),
              0);
    Keyframe& common = keyframes[100 / stride];  // every[100], 10.5 s into the drive, turning
    std::vector<ceres::ResidualBlockId> blocks;
    problem->GetResidualBlocksForParameterBlock(common.v_W_I.data(), &blocks);
    ASSERT_EQ(blocks.size(), 1u);
    std::vector<double*> parameters;
    problem->GetParameterBlocksForResidualBlock(blocks[0], &parameters);
    const auto track = std::find(parameters.begin(), parameters.end(), &calibration.track_width_m);
    ASSERT_NE(track, parameters.end());
    std::vector<double> residuals(4);
    std::vector<std::vector<double>> jacobian_storage(parameters.size());
    std::vector<double*> jacobians(parameters.size(), nullptr);
    const size_t t = static_cast<size_t>(track - parameters.begin());
    jacobian_storage[t].resize(4);
    jacobians[t] = jacobian_storage[t].data();
    ASSERT_TRUE(problem->EvaluateResidualBlock(blocks[0], false, nullptr, residuals.data(),
                                               jacobians.data()));
    d_yaw_row_d_track[stride - 1] = jacobian_storage[t][1];
  }
  ASSERT_NE(d_yaw_row_d_track[0], 0.0);
  EXPECT_NEAR(d_yaw_row_d_track[1] / d_yaw_row_d_track[0], std::sqrt(2.0), 1e-3);
}

// The yaw-rate row reads the gyro about the axis the vehicle turns about, measured from the
// keyframes' readings (Eq. K13c), not about V's up axis through the mount: a mount rolled 5 deg
// off (held) reads the yaw rate cos(5 deg) of its size there, and the track absorbs it.
// Noise-free drive, true keyframes and radii. Measured: 7.3 mm long about V's up axis, -0.11 mm
// about the measured axis (the body's roll rates lean it by about half a degree).
TEST_F(KeyframeSensorFactorsTest, TheYawRowDoesNotDependOnTheMountsTilt) {
  const sensors::Calibration& truth = exact_simulator_->true_calibration();
  factors::WheelFactorOptions rows = factors::WheelFactorOptions::FromEncoderNoise(
      exact_simulator_->options().wheel.config, truth.wheel_radius_left_m, truth.track_width_m);
  rows.non_holonomic = false;  // the rows the tilted mount would pull
  const Eigen::Quaterniond rolled =
      truth.q_I_V * geometry::Exp(Eigen::Vector3d(5.0 * kDegToRad, 0.0, 0.0));
  const double about_v_mm = TrackErrorMm(rolled, rows, 0.2, 0.0);
  const double about_axis_mm = TrackErrorMm(rolled, rows, 0.2, 1.0);
  std::cout << "track about V's up axis " << about_v_mm << " mm off, about the measured axis "
            << about_axis_mm << " mm\n";
  EXPECT_GT(about_v_mm, 4.0);
  EXPECT_LT(std::abs(about_axis_mm), 0.2);
}

// The simulated encoder log converted into the two other wheel forms with known intrinsics:
// wheel speeds scaled by 1/1.02 and 1/0.99, and a controller twist with k_v = 0.96 and a skid
// track b_eff = 1.9 m against b_ctrl = 1.62 m. From the nominal guess (scales 1, b_eff = b_ctrl)
// with true keyframes, the factors of each form recover their own intrinsics.
TEST_F(KeyframeSensorFactorsTest, WheelFormsRecoverTheirIntrinsics) {
  const sensors::Calibration& truth = noisy_simulator_->true_calibration();
  const double true_scale_left = 1.02, true_scale_right = 0.99;
  const double true_speed_scale = 0.96, true_effective_track_m = 1.9, controller_track_m = 1.62;
  WheelData speeds, twist;
  speeds.form = sensors::WheelForm::kLinearSpeeds;
  twist.form = sensors::WheelForm::kSpeedYawRate;
  twist.controller_track_m = controller_track_m;
  for (const sensors::WheelSample& w : noisy_->wheel) {
    const double left_m_s = truth.wheel_radius_left_m * w.left_rad_s;
    const double right_m_s = truth.wheel_radius_right_m * w.right_rad_s;
    speeds.speeds.push_back(
        {w.t_ns, left_m_s / true_scale_left, right_m_s / true_scale_right, false, 0.0, 0.0});
    const double v = 0.5 * (left_m_s + right_m_s);
    const double yaw_rate = (right_m_s - left_m_s) / truth.track_width_m;
    twist.odometry.push_back(
        {w.t_ns, v / true_speed_scale,
         yaw_rate * true_effective_track_m / (true_speed_scale * controller_track_m)});
  }
  sensors::WheelConfig config = noisy_simulator_->options().wheel.config;
  config.noise_m_s = 0.33 * config.noise_rad_s;  // the encoders' noise as speed noise
  config.yaw_rate_noise_rad_s = std::sqrt(2.0) * config.noise_m_s / truth.track_width_m;
  for (const WheelData* data : {&speeds, &twist}) {
    const bool is_twist = data == &twist;
    std::vector<Keyframe> keyframes = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
    sensors::Calibration calibration = noisy_simulator_->nominal_calibration();
    calibration.q_I_V = truth.q_I_V;
    calibration.p_I_V = truth.p_I_V;
    calibration.effective_track_m = controller_track_m;
    const sensors::Calibration nominal = calibration;
    auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
    KeyframeWheelOptions options;
    options.factor = is_twist ? factors::WheelFactorOptions::FromOdometryNoise(config)
                              : factors::WheelFactorOptions::FromWheelSpeedNoise(
                                    config, calibration.track_width_m);
    options.estimate_vehicle_rotation = false;
    options.estimate_vehicle_translation = false;
    const int added = AddWheelFactors(problem.get(), noisy_->imu.samples, *data, &keyframes,
                                      &calibration, options);
    EXPECT_EQ(added, static_cast<int>(keyframes.size()));
    const ceres::Solver::Summary summary = Solve(problem.get());
    ASSERT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
    if (is_twist) {
      const double k_percent = PercentError(calibration.odometry_speed_scale, true_speed_scale);
      const double b_percent = PercentError(calibration.effective_track_m, true_effective_track_m);
      std::cout << added << " odometry factors: k_v error " << k_percent << " %, b_eff error "
                << b_percent << " % (nominal " << PercentError(1.0, true_speed_scale) << " %, "
                << PercentError(controller_track_m, true_effective_track_m) << " %)\n";
      EXPECT_LT(std::abs(k_percent), 0.05);
      EXPECT_LT(std::abs(b_percent), 0.2);
      // The blocks of the other forms are not touched.
      EXPECT_EQ(calibration.wheel_radius_left_m, nominal.wheel_radius_left_m);
      EXPECT_EQ(calibration.track_width_m, nominal.track_width_m);
    } else {
      const double left_percent = PercentError(calibration.wheel_speed_scale_left, true_scale_left);
      const double right_percent =
          PercentError(calibration.wheel_speed_scale_right, true_scale_right);
      const double track_percent = PercentError(calibration.track_width_m, truth.track_width_m);
      std::cout << added << " wheel-speed factors: scale error left " << left_percent
                << " %, right " << right_percent << " %, track width " << track_percent << " %\n";
      EXPECT_LT(std::abs(left_percent), 0.05);
      EXPECT_LT(std::abs(right_percent), 0.05);
      EXPECT_LT(std::abs(track_percent), 0.2);
      EXPECT_EQ(calibration.odometry_speed_scale, nominal.odometry_speed_scale);
      EXPECT_EQ(calibration.wheel_radius_left_m, nominal.wheel_radius_left_m);
    }
    EXPECT_EQ(calibration.p_I_V, truth.p_I_V);
  }
  // Held, the form's intrinsics stay at the nominal guess.
  std::vector<Keyframe> keyframes = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
  sensors::Calibration calibration = noisy_simulator_->nominal_calibration();
  auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
  KeyframeWheelOptions held;
  held.factor = factors::WheelFactorOptions::FromOdometryNoise(config);
  held.estimate_radii = false;
  held.estimate_track_width = false;
  ASSERT_GT(
      AddWheelFactors(problem.get(), noisy_->imu.samples, twist, &keyframes, &calibration, held),
      0);
  EXPECT_TRUE(problem->IsParameterBlockConstant(&calibration.odometry_speed_scale));
  EXPECT_TRUE(problem->IsParameterBlockConstant(&calibration.effective_track_m));
  twist.controller_track_m = 0.0;
  EXPECT_THROW(
      AddWheelFactors(problem.get(), noisy_->imu.samples, twist, &keyframes, &calibration, held),
      Error);
}

// With one shared radius the left block takes the mean of the two true radii (the forward
// speed depends on their mean; their 0.27 % difference is left as a yaw-rate error on
// straights, which the Huber loss bounds) and the right block is not touched.
TEST_F(KeyframeSensorFactorsTest, SharedWheelRadius) {
  std::vector<Keyframe> keyframes = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
  const sensors::Calibration& truth = noisy_simulator_->true_calibration();
  sensors::Calibration calibration = noisy_simulator_->nominal_calibration();
  calibration.q_I_V = truth.q_I_V;
  calibration.p_I_V = truth.p_I_V;
  const double nominal_right_m = calibration.wheel_radius_right_m;
  auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
  KeyframeWheelOptions options;
  options.factor = factors::WheelFactorOptions::FromEncoderNoise(
      noisy_simulator_->options().wheel.config, calibration.wheel_radius_left_m,
      calibration.track_width_m);
  options.factor.shared_radius = true;
  options.estimate_vehicle_rotation = false;
  options.estimate_vehicle_translation = false;
  ASSERT_GT(AddWheelFactors(problem.get(), noisy_->imu.samples, noisy_->wheel, &keyframes,
                            &calibration, options),
            0);
  const ceres::Solver::Summary summary = Solve(problem.get());
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
  const double mean_m = 0.5 * (truth.wheel_radius_left_m + truth.wheel_radius_right_m);
  const double shared_percent = PercentError(calibration.wheel_radius_left_m, mean_m);
  std::cout << "shared radius error " << shared_percent << " % of the mean true radius\n";
  EXPECT_LT(std::abs(shared_percent), 0.05);
  EXPECT_EQ(calibration.wheel_radius_right_m, nominal_right_m);
}

// Fix positions interpolated 30 ms after each 10 Hz fix against the true antenna position:
// linear interpolation errs by s (1 - s) a dt^2 / 2 for an acceleration a (at most a dt^2 / 8).
TEST_F(KeyframeSensorFactorsTest, InterpolatedFixesFollowTheAntenna) {
  const sensors::EnuConverter converter = Converter(*exact_simulator_);
  const Eigen::Vector3d& p_I_A = exact_simulator_->true_calibration().p_I_A;
  double max_error_m = 0.0;
  int interpolated = 0;
  for (const Keyframe& kf : TrueKeyframes(*exact_simulator_, exact_->imu, 0.03)) {
    factors::GnssMeasurement m;
    if (!InterpolateGnss(exact_->gnss.fixes, converter, kf.t_ns, 0.25, &m)) continue;
    ++interpolated;
    max_error_m = std::max(max_error_m, (m.p_W_A - (kf.p_W_I + kf.q_W_I * p_I_A)).norm());
  }
  std::cout << interpolated << " interpolated fixes, max error " << max_error_m << " m\n";
  EXPECT_GT(interpolated, 200);
  EXPECT_LT(max_error_m, 0.005);

  // A fix exactly at the requested time is used alone; none is found past the last fix.
  const sensors::GnssFix& fix = exact_->gnss.fixes[10];
  factors::GnssMeasurement m;
  ASSERT_TRUE(InterpolateGnss(exact_->gnss.fixes, converter, fix.t_ns, 0.25, &m));
  EXPECT_EQ(m.p_W_A, converter.ToEnu(fix));
  EXPECT_EQ(m.sigma_enu_m, fix.std_enu_m);
  EXPECT_FALSE(
      InterpolateGnss(exact_->gnss.fixes, converter, exact_->gnss.fixes.back().t_ns + 1, 0.25, &m));
}

// A 1 Hz receiver (every tenth fix of the noise-free log) and keyframes every 0.1 s: ten
// keyframes between two fixes. Interpolated to each keyframe, every fix's information entered
// ten rows at its full sigma, and the straight line between fixes a second apart missed the
// curving antenna by many sigmas. Each fix now serves its nearest keyframe once, the state
// carried to it by the IMU (Eq. K16, K17), and the rows vanish at the truth.
TEST_F(KeyframeSensorFactorsTest, SparseFixesServeOneKeyframeEach) {
  sensors::GnssFixes fixes;
  for (size_t i = 0; i < exact_->gnss.fixes.size(); i += 10) {
    fixes.push_back(exact_->gnss.fixes[i]);
  }
  std::vector<Keyframe> keyframes = TrueKeyframes(*exact_simulator_, exact_->imu, kPhaseS);
  sensors::Calibration calibration = exact_simulator_->true_calibration();
  auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
  KeyframeGnssOptions options;
  options.loss = factors::LossOptions();
  options.max_fix_gap_s = 1.25;
  options.estimate_lever_arm = false;
  const int added = AddGnssFactors(problem.get(), exact_->imu.samples, fixes,
                                   Converter(*exact_simulator_), &keyframes, &calibration, options);
  EXPECT_LE(added, static_cast<int>(fixes.size()));
  EXPECT_GT(added, static_cast<int>(fixes.size()) * 8 / 10);
  double cost = 0.0;
  problem->Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
  const double whitened_rms = std::sqrt(2.0 * cost / (3.0 * added));
  std::cout << added << " GNSS factors for " << fixes.size() << " fixes and " << keyframes.size()
            << " keyframes; whitened RMS at the truth " << whitened_rms << "\n";
  EXPECT_LT(whitened_rms, 0.1);
}

// Fixes every period_s from the start of the noise-free drive at its true antenna positions,
// with seeded noise of their stated 3 cm (6 cm up), and true keyframes every spacing_s from
// 0.5 s + phase_s; the GNSS rows of AddGnssFactors on them, held at the truth.
struct GnssRowsAtTruth {
  int fixes_in_span = 0;  // fixes within half a keyframe spacing of the keyframes' span
  int rows = 0;
  int interpolated_rows = 0;  // rows of the interpolating factor (3 parameter blocks)
  double whitened_rms = 0.0;
};

GnssRowsAtTruth RowsAtTruth(const sim::Simulator& simulator, const sim::SimulatedLog& log,
                            double period_s, double spacing_s, double phase_s) {
  std::mt19937_64 random(17);
  std::normal_distribution<double> noise(0.0, 1.0);
  const sim::GnssSimOptions& g = simulator.options().gnss;
  const sensors::EnuConverter enu(g.origin_lat_deg, g.origin_lon_deg, g.origin_alt_m);
  sensors::Calibration calibration = simulator.true_calibration();
  sensors::GnssFixes fixes;
  for (double t_s = 0.0; t_s < simulator.options().duration_s; t_s += period_s) {
    const Keyframe truth = TrueKeyframe(log.imu, simulator.StampAt(t_s));
    sensors::GnssFix fix;
    fix.t_ns = truth.t_ns;
    fix.std_enu_m = Eigen::Vector3d(0.03, 0.03, 0.06);
    const Eigen::Vector3d lla = enu.ToGeodetic(
        truth.p_W_I + truth.q_W_I * calibration.p_I_A +
        fix.std_enu_m.cwiseProduct(Eigen::Vector3d(noise(random), noise(random), noise(random))));
    fix.lat_deg = lla.x();
    fix.lon_deg = lla.y();
    fix.alt_m = lla.z();
    fixes.push_back(fix);
  }
  std::vector<Keyframe> keyframes;
  for (double t_s = 0.5 + phase_s; t_s < simulator.options().duration_s - 0.5; t_s += spacing_s) {
    keyframes.push_back(TrueKeyframe(log.imu, simulator.StampAt(t_s)));
  }
  geometry::RightQuaternionManifold quaternion_manifold;
  ceres::Problem problem(ManifoldsNotOwned());
  AddKeyframeRotations(&keyframes, &quaternion_manifold, &problem);
  KeyframeGnssOptions options;
  options.loss = factors::LossOptions();
  options.max_fix_gap_s = 2.5 * period_s;
  AddGnssFactors(&problem, log.imu.samples, fixes, enu, &keyframes, &calibration, options);
  GnssRowsAtTruth out;
  const int64_t margin_ns = SecondsToNs(0.5 * spacing_s);
  for (const sensors::GnssFix& fix : fixes) {
    out.fixes_in_span += fix.t_ns >= keyframes.front().t_ns - margin_ns &&
                         fix.t_ns <= keyframes.back().t_ns + margin_ns;
  }
  std::vector<ceres::ResidualBlockId> blocks;
  problem.GetResidualBlocks(&blocks);
  out.rows = static_cast<int>(blocks.size()) / 2;  // a horizontal and a vertical block each
  for (const ceres::ResidualBlockId id : blocks) {
    std::vector<double*> parameters;
    problem.GetParameterBlocksForResidualBlock(id, &parameters);
    out.interpolated_rows += parameters.size() == 3 ? 1 : 0;
  }
  out.interpolated_rows /= 2;
  double cost = 0.0;
  problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
  out.whitened_rms = std::sqrt(2.0 * cost / (3.0 * out.rows));
  return out;
}

// Keyframes about as dense as the fixes but off their stamps share fixes: one entered two
// neighbouring keyframes' interpolated rows (weights 1 - s and s) at the full sigma of Eq. K2.
// Each fix now serves its nearest keyframe once (Eq. K17), so the rows are the fixes and, at
// the truth, scatter as their sigma says (measured 1.00-1.02). Interpolated, on the noise-free
// drive's antenna with 3 cm of noise:
// - 5 Hz fixes, keyframes every 0.2 s midway: 146 rows for 147 fixes, whitened RMS 0.71 (an
//   interpolated value averages two fixes' noise; and the line between fixes 0.2 s apart
//   missed the curving antenna, which biased the lever arm by 1.6 mm at a sigma of 2.5 mm);
// - 8 Hz fixes, keyframes every 0.2 s: 145 rows for 232 fixes, RMS 0.83;
// - keyframes every 0.05 s, every second one on a 10 Hz fix: 580 rows for 290 fixes, each fix
//   in three rows at weights 1/2, 1, 1/2: RMS 0.87, and the lever arm's stated sigma 0.7 of its
//   scatter over noise draws (the information counted twice).
TEST_F(KeyframeSensorFactorsTest, SharedFixesServeOneKeyframeEach) {
  struct Case {
    double period_s, spacing_s, phase_s;
  };
  for (const Case c : {Case{0.2, 0.2, 0.0}, Case{0.125, 0.2, 0.037}, Case{0.1, 0.05, 0.0}}) {
    const GnssRowsAtTruth rows =
        RowsAtTruth(*exact_simulator_, *exact_, c.period_s, c.spacing_s, c.phase_s);
    std::cout << "fixes every " << c.period_s << " s, keyframes every " << c.spacing_s
              << " s: " << rows.rows << " rows (" << rows.interpolated_rows << " interpolated) for "
              << rows.fixes_in_span << " fixes; whitened RMS at the truth " << rows.whitened_rms
              << "\n";
    EXPECT_LE(rows.rows, rows.fixes_in_span);
    EXPECT_GE(rows.rows, rows.fixes_in_span - 2);
    EXPECT_EQ(rows.interpolated_rows, 0);
    EXPECT_GT(rows.whitened_rms, 0.9);
    EXPECT_LT(rows.whitened_rms, 1.1);
  }
}

// Where no fix enters two keyframes' rows, each keyframe keeps its interpolated fix (Eq. K1):
// 10 Hz fixes with keyframes every 0.2 s off their stamps, and a keyframe on every fix.
TEST_F(KeyframeSensorFactorsTest, UnsharedFixesStayInterpolated) {
  for (const double spacing_s : {0.2, 0.1}) {
    const GnssRowsAtTruth rows =
        RowsAtTruth(*exact_simulator_, *exact_, 0.1, spacing_s, spacing_s == 0.2 ? 0.037 : 0.0);
    std::cout << "keyframes every " << spacing_s << " s: " << rows.rows << " rows, "
              << rows.interpolated_rows << " interpolated; whitened RMS at the truth "
              << rows.whitened_rms << "\n";
    EXPECT_GT(rows.rows, 100);
    EXPECT_EQ(rows.interpolated_rows, rows.rows);
  }
}

// A keyframe whose bracketing wheel samples are more than max_wheel_gap_s apart gets none.
TEST_F(KeyframeSensorFactorsTest, WheelDropoutsLeaveKeyframesWithoutFactors) {
  std::vector<Keyframe> keyframes = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
  sensors::WheelSamples wheel;
  const int64_t dropout_begin_ns = noisy_simulator_->StampAt(10.0);
  const int64_t dropout_end_ns = noisy_simulator_->StampAt(11.0);
  for (const sensors::WheelSample& w : noisy_->wheel) {
    if (w.t_ns < dropout_begin_ns || w.t_ns >= dropout_end_ns) wheel.push_back(w);
  }
  int inside = 0;
  for (const Keyframe& kf : keyframes)
    inside += kf.t_ns > dropout_begin_ns && kf.t_ns < dropout_end_ns;
  sensors::Calibration calibration = noisy_simulator_->nominal_calibration();
  auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
  const int added =
      AddWheelFactors(problem.get(), noisy_->imu.samples, wheel, &keyframes, &calibration);
  EXPECT_EQ(inside, 10);
  EXPECT_EQ(added, static_cast<int>(keyframes.size()) - inside);
}

// Every n-th sample, from the first.
template <typename Sample>
std::vector<Sample> EveryNth(const std::vector<Sample>& samples, size_t n) {
  std::vector<Sample> out;
  for (size_t i = 0; i < samples.size(); i += n) out.push_back(samples[i]);
  return out;
}

// A slower rig, the log's samples thinned to an IMU at 25 Hz, wheels at 10 Hz and fixes at 1 Hz,
// with the options' default gaps: they follow each sensor's own rate (Eq. T1, T3), so the
// keyframes get their rows and the track its placement. The limits written for 200 / 100 / 10 Hz,
// the defaults before, left every row out and placed no keyframe.
TEST_F(KeyframeSensorFactorsTest, DefaultGapsFollowTheSensorsRates) {
  const sensors::ImuSamples imu = EveryNth(noisy_->imu.samples, 8);
  const sensors::WheelSamples wheel = EveryNth(noisy_->wheel, 10);
  const sensors::GnssFixes fixes = EveryNth(noisy_->gnss.fixes, 10);
  const sensors::EnuConverter enu = Converter(*noisy_simulator_);
  std::vector<Keyframe> keyframes = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
  struct Rows {
    int wheel = 0, gnss = 0, planar = 0;
  };
  const auto rows = [&](const KeyframeWheelOptions& wheel_options,
                        const KeyframeGnssOptions& gnss_options,
                        const PlanarRotationOptions& planar_options) {
    sensors::Calibration calibration = noisy_simulator_->nominal_calibration();
    auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
    Rows out;
    out.wheel = AddWheelFactors(problem.get(), imu, wheel, &keyframes, &calibration, wheel_options);
    out.gnss =
        AddGnssFactors(problem.get(), imu, fixes, enu, &keyframes, &calibration, gnss_options);
    out.planar =
        AddPlanarRotationFactors(problem.get(), imu, &keyframes, &calibration, planar_options)
            .added;
    return out;
  };
  PlanarRotationOptions planar;
  planar.sigma_rad_s = 0.01;
  const Rows derived = rows({}, {}, planar);
  KeyframeWheelOptions wheel_200_100;
  wheel_200_100.max_wheel_gap_s = 0.025;
  wheel_200_100.max_imu_gap_s = 0.0125;
  KeyframeGnssOptions gnss_10;
  gnss_10.max_fix_gap_s = 0.25;
  gnss_10.max_imu_gap_s = 0.0125;
  PlanarRotationOptions planar_200 = planar;
  planar_200.max_imu_gap_s = 0.0125;
  const Rows fixed = rows(wheel_200_100, gnss_10, planar_200);
  std::cout << keyframes.size() << " keyframes, " << fixes.size()
            << " fixes; rows with the derived gaps: wheel " << derived.wheel << ", GNSS "
            << derived.gnss << ", planar " << derived.planar
            << "; with 200 / 100 / 10 Hz's: " << fixed.wheel << ", " << fixed.gnss << ", "
            << fixed.planar << "\n";
  const int n = static_cast<int>(keyframes.size());
  EXPECT_EQ(derived.wheel, n);
  EXPECT_EQ(derived.planar, n);
  EXPECT_GE(derived.gnss, static_cast<int>(fixes.size()) - 6);  // each fix once, outages aside
  EXPECT_EQ(fixed.wheel, 0);
  EXPECT_EQ(fixed.gnss, 0);
  EXPECT_EQ(fixed.planar, 0);

  const sensors::Calibration& c = noisy_simulator_->true_calibration();
  std::vector<Keyframe> placed = keyframes;
  const GnssPlacement placement = PlaceKeyframesOnGnss(&placed, fixes, enu, c.p_I_A, c.q_I_V);
  std::cout << placement.num_placed << " keyframes placed on +-2.5 s of fixes\n";
  // Measured 102: the log's outages and multipath leave the others fewer than five fixes.
  EXPECT_GT(placement.num_placed, n / 4);
  GnssPlacementOptions one_second;
  one_second.half_width_s = 1.0;
  EXPECT_THROW(PlaceKeyframesOnGnss(&placed, fixes, enu, c.p_I_A, c.q_I_V, one_second), Error);
  std::vector<Keyframe> aligned = keyframes;
  EXPECT_GT(AlignKeyframesToGnss(&aligned, fixes, enu, c.p_I_A).num_pairs, n * 3 / 4);
  EXPECT_GT(RemoveOdometryDrift(&aligned, fixes, enu, c.p_I_A).num_pairs, n * 3 / 4);
}

// Wheels and a receiver on clocks of their own (Eq. K16, K17): the noise-free log restamped as a
// wheel clock 0.2 s late and a GNSS clock 0.15 s early, read through offsets started 50 ms
// off (as a cross-correlation leaves them), with the true keyframes and calibration held: the
// solve finds both offsets; held at their true values, the factors vanish as the unshifted
// ones do on the aligned log.
TEST_F(KeyframeSensorFactorsTest, ShiftedWheelsAndFixesFindTheirClockOffsets) {
  constexpr double kWheelOffsetS = -0.2, kGnssOffsetS = 0.15;
  sensors::WheelSamples wheel = exact_->wheel;
  for (sensors::WheelSample& w : wheel) w.t_ns -= SecondsToNs(kWheelOffsetS);
  sensors::GnssFixes fixes = exact_->gnss.fixes;
  for (sensors::GnssFix& f : fixes) f.t_ns -= SecondsToNs(kGnssOffsetS);
  std::vector<Keyframe> keyframes = TrueKeyframes(*exact_simulator_, exact_->imu, kPhaseS);
  sensors::Calibration calibration = exact_simulator_->true_calibration();
  calibration.time_offset_wheel_imu_s = kWheelOffsetS + 0.05;
  calibration.time_offset_gnss_imu_s = kGnssOffsetS - 0.05;
  auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
  KeyframeWheelOptions wheel_options;
  wheel_options.estimate_vehicle_rotation = wheel_options.estimate_vehicle_translation = false;
  wheel_options.estimate_radii = wheel_options.estimate_track_width = false;
  wheel_options.estimate_time_offset = true;
  const int wheel_added = AddWheelFactors(problem.get(), exact_->imu.samples, wheel, &keyframes,
                                          &calibration, wheel_options);
  KeyframeGnssOptions gnss_options;
  gnss_options.estimate_lever_arm = false;
  gnss_options.estimate_time_offset = true;
  const int gnss_added =
      AddGnssFactors(problem.get(), exact_->imu.samples, fixes, Converter(*exact_simulator_),
                     &keyframes, &calibration, gnss_options);
  EXPECT_GT(wheel_added, static_cast<int>(keyframes.size()) * 9 / 10);
  EXPECT_GT(gnss_added, static_cast<int>(keyframes.size()) / 2);
  EXPECT_FALSE(problem->IsParameterBlockConstant(&calibration.time_offset_wheel_imu_s));
  const ceres::Solver::Summary summary = Solve(problem.get());
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
  const double wheel_error_ms = 1e3 * (calibration.time_offset_wheel_imu_s - kWheelOffsetS);
  const double gnss_error_ms = 1e3 * (calibration.time_offset_gnss_imu_s - kGnssOffsetS);
  std::cout << wheel_added << " wheel, " << gnss_added << " GNSS factors; offset errors "
            << wheel_error_ms << " ms (wheel), " << gnss_error_ms << " ms (GNSS)\n";
  // Measured -0.018 ms and -0.003 ms: Eq. K16 carries the state with the IMU's lines over
  // +-0.1 s, which follow the body's sway on its suspension closely but not exactly.
  EXPECT_LT(std::abs(wheel_error_ms), 0.05);
  EXPECT_LT(std::abs(gnss_error_ms), 0.01);

  // Not estimated: the offset block is held, and a keyframe whose shifted instant falls in a
  // wheel dropout gets no factor (no sample within max_wheel_gap_s / 2 of t_k - offset).
  sensors::WheelSamples with_dropout;
  const int64_t begin_ns = exact_simulator_->StampAt(10.0) - SecondsToNs(kWheelOffsetS);
  const int64_t end_ns = exact_simulator_->StampAt(11.0) - SecondsToNs(kWheelOffsetS);
  for (const sensors::WheelSample& w : wheel) {
    if (w.t_ns < begin_ns || w.t_ns >= end_ns) with_dropout.push_back(w);
  }
  sensors::Calibration held = exact_simulator_->true_calibration();
  held.time_offset_wheel_imu_s = kWheelOffsetS;
  auto held_problem = ProblemWithConstantKeyframes(&keyframes, &held);
  const int held_added = AddWheelFactors(held_problem.get(), exact_->imu.samples, with_dropout,
                                         &keyframes, &held, KeyframeWheelOptions());
  EXPECT_TRUE(held_problem->IsParameterBlockConstant(&held.time_offset_wheel_imu_s));
  EXPECT_EQ(held_added, wheel_added - 10);
}

// The clocks end where the data put them, not where the solve starts them: on the noisy drive
// (true clocks 0) with free keyframes under IMU factors, the wheel and GNSS clocks started
// 20 ms early, on time or 20 ms late end within 0.1 ms of one another (measured: 0.37 and
// -0.70 ms from each start). Reading the samples at
// t_k - offset made the cost piecewise linear in the offset with a smoothed slope for its
// Jacobian, and a straight drive's clocks ended 14.7 and 15.4 ms off when started at -20 ms,
// +14.9 and +14.5 ms when started at +20 ms, at a sigma of 2.2 ms.
TEST_F(KeyframeSensorFactorsTest, ClocksDoNotDependOnWhereTheSolveStartsThem) {
  // The wheel and GNSS clocks (ms) one solve ends at from `start_ms`.
  const auto solve = [&](const Eigen::Vector2d& start_ms) -> Eigen::Vector2d {
    std::vector<Keyframe> keyframes = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
    sensors::Calibration calibration = noisy_simulator_->true_calibration();
    calibration.time_offset_wheel_imu_s = 1e-3 * start_ms(0);
    calibration.time_offset_gnss_imu_s = 1e-3 * start_ms(1);
    ceres::Problem problem(ManifoldsNotOwned());
    AddKeyframeRotations(&keyframes, &quaternion_manifold_, &problem);
    problem.AddParameterBlock(calibration.q_I_V.coeffs().data(), 4, &quaternion_manifold_);
    KeyframeImuOptions imu;
    imu.noise = noisy_simulator_->options().imu.noise;
    AddImuFactors(&problem, noisy_->imu.samples, &keyframes, imu);
    AddBiasPriors(&problem, &keyframes.front(), 1e-3, 0.05);
    KeyframeWheelOptions wheel;
    wheel.factor = factors::WheelFactorOptions::FromEncoderNoise(
        noisy_simulator_->options().wheel.config, calibration.wheel_radius_left_m,
        calibration.track_width_m);
    wheel.estimate_vehicle_rotation = wheel.estimate_vehicle_translation = false;
    wheel.estimate_track_width = false;
    wheel.estimate_time_offset = true;
    EXPECT_GT(AddWheelFactors(&problem, noisy_->imu.samples, noisy_->wheel, &keyframes,
                              &calibration, wheel),
              250);
    KeyframeGnssOptions gnss;
    gnss.estimate_lever_arm = false;
    gnss.estimate_time_offset = true;
    EXPECT_GT(AddGnssFactors(&problem, noisy_->imu.samples, noisy_->gnss.fixes,
                             Converter(*noisy_simulator_), &keyframes, &calibration, gnss),
              200);
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    options.max_num_iterations = 50;
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    EXPECT_EQ(summary.termination_type, ceres::CONVERGENCE) << summary.BriefReport();
    return Eigen::Vector2d(calibration.time_offset_wheel_imu_s,
                           calibration.time_offset_gnss_imu_s) *
           1e3;
  };
  // Each solve pairs the keyframes with the samples nearest the clocks it starts from (Eq.
  // K17); as the offline calibration does, the factors are paired again at the clocks a solve
  // ends at, here five solves in all (the offline calibration's limit).
  const auto solve_until_paired = [&](double start_ms) {
    Eigen::Vector2d clocks_ms = solve(Eigen::Vector2d::Constant(start_ms));
    for (int pass = 0; pass < 4; ++pass) clocks_ms = solve(clocks_ms);
    return clocks_ms;
  };
  const Eigen::Vector2d early_ms = solve_until_paired(-20.0);
  const Eigen::Vector2d on_time_ms = solve_until_paired(0.0);
  const Eigen::Vector2d late_ms = solve_until_paired(20.0);
  std::cout << "wheel and GNSS clocks (ms) started at -20 ms: " << early_ms.transpose()
            << "; at 0: " << on_time_ms.transpose() << "; at +20 ms: " << late_ms.transpose()
            << "\n";
  // Before the factors were paired again, the first solves ended at (-2.0, -3.0), (0.3, -0.9)
  // and (2.0, 1.2) ms: the samples nearest a clock 20 ms off are not those nearest the truth.
  EXPECT_LT((early_ms - on_time_ms).cwiseAbs().maxCoeff(), 0.1);
  EXPECT_LT((late_ms - on_time_ms).cwiseAbs().maxCoeff(), 0.1);
  EXPECT_LT(on_time_ms.cwiseAbs().maxCoeff(), 3.0);
}

// The non-holonomic rows' model error is the body's pitch and roll on its suspension, which
// follow the acceleration: on the noise-free drive with the true state and calibration, the
// vertical speed of the rear axle in V is far from white (correlated over seconds), and
// AddWheelFactors scales the lateral and vertical rows' sigmas by sqrt(2 tau / dt) with their
// own tau (the correlated-error scaling, docs/keyframe_factors.md) and no other row.
TEST_F(KeyframeSensorFactorsTest, NonHolonomicRowsAreWeightedForTheirCorrelation) {
  const auto residuals = [&](double lateral_tau_s, double vertical_tau_s) {
    std::vector<Keyframe> keyframes = TrueKeyframes(*exact_simulator_, exact_->imu, kPhaseS);
    sensors::Calibration calibration = exact_simulator_->true_calibration();
    auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
    KeyframeWheelOptions options;
    options.lateral_correlation_s = lateral_tau_s;
    options.vertical_correlation_s = vertical_tau_s;
    options.loss = factors::LossOptions();  // plain least squares: raw whitened rows
    EXPECT_GT(AddWheelFactors(problem.get(), exact_->imu.samples, exact_->wheel, &keyframes,
                              &calibration, options),
              200);
    std::vector<double> r;
    problem->Evaluate(ceres::Problem::EvaluateOptions(), nullptr, &r, nullptr, nullptr);
    return r;
  };
  const std::vector<double> white = residuals(0.0, 0.0);
  const std::vector<double> correlated = residuals(2.0, 0.5);
  ASSERT_EQ(white.size(), correlated.size());
  ASSERT_EQ(white.size() % 4, 0u);
  const double lateral_scale = std::sqrt(2.0 * 2.0 / kKeyframeSpacingS);
  const double vertical_scale = std::sqrt(2.0 * 0.5 / kKeyframeSpacingS);
  std::vector<double> vertical;
  for (size_t i = 0; i < white.size(); i += 4) {
    EXPECT_EQ(correlated[i], white[i]);
    EXPECT_EQ(correlated[i + 1], white[i + 1]);
    EXPECT_NEAR(correlated[i + 2] * lateral_scale, white[i + 2], 1e-12);
    EXPECT_NEAR(correlated[i + 3] * vertical_scale, white[i + 3], 1e-12);
    vertical.push_back(white[i + 3]);
  }
  // The integral time of the vertical row's autocorrelation (up to its first zero): white
  // noise would give half a keyframe spacing.
  double mean = 0.0;
  for (double v : vertical) mean += v;
  mean /= static_cast<double>(vertical.size());
  const auto covariance = [&](size_t lag) {
    double c = 0.0;
    for (size_t i = 0; i + lag < vertical.size(); ++i) {
      c += (vertical[i] - mean) * (vertical[i + lag] - mean);
    }
    return c / static_cast<double>(vertical.size());
  };
  const double c0 = covariance(0);
  double integral_time_s = 0.5 * kKeyframeSpacingS;
  for (size_t lag = 1; lag < vertical.size() && covariance(lag) > 0.0; ++lag) {
    integral_time_s += kKeyframeSpacingS * covariance(lag) / c0;
  }
  // Over +-10 s the negative lobe (a speed following the acceleration averages out) cancels
  // most of it. The vertical row's default is twice that integral, which is what sets the
  // variance of a long average; the lateral row's is the integral to the first zero.
  double integral_10s_s = 0.5 * kKeyframeSpacingS;
  for (size_t lag = 1; lag < 100; ++lag) integral_10s_s += kKeyframeSpacingS * covariance(lag) / c0;
  const double rms_m_s = 0.05 * std::sqrt(c0);
  std::cout << "noise-free vertical rear-axle speed: rms " << rms_m_s
            << " m/s, autocorrelation integral time " << integral_time_s << " s to its first zero, "
            << integral_10s_s << " s over 10 s\n";
  EXPECT_GT(rms_m_s, 0.005);
  EXPECT_GT(integral_time_s, 1.0);
  EXPECT_LT(integral_10s_s, 0.5);
  EXPECT_NEAR(KeyframeWheelOptions().vertical_correlation_s, 2.0 * integral_10s_s, 0.05);
  EXPECT_NEAR(KeyframeWheelOptions().lateral_correlation_s, integral_time_s, 0.1);

  // A negative or non-finite correlation time is refused, for either row.
  std::vector<Keyframe> keyframes = TrueKeyframes(*exact_simulator_, exact_->imu, kPhaseS);
  sensors::Calibration calibration = exact_simulator_->true_calibration();
  auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
  KeyframeWheelOptions negative, not_finite;
  negative.lateral_correlation_s = -1.0;
  not_finite.vertical_correlation_s = std::nan("");
  for (const auto& [options, name] : {std::pair{negative, "lateral_correlation_s"},
                                      std::pair{not_finite, "vertical_correlation_s"}}) {
    try {
      AddWheelFactors(problem.get(), exact_->imu.samples, exact_->wheel, &keyframes, &calibration,
                      options);
      ADD_FAILURE() << name << " accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
}

// A road car's rear axle slips out of a turn by its cornering compliance c (Eq. K6c): each
// keyframe's lateral row takes sqrt(s0^2 + (c v^2 omega)^2) of its speed v and turning rate
// omega (the gyro about V's up axis) for the straight-driving s0, and no other row changes.
TEST_F(KeyframeSensorFactorsTest, TheLateralRowTakesTheSlipOfItsTurn) {
  constexpr double kStraightSlipMS = 0.01;  // a road car's (sim::RoadCarWheelConfig)
  const std::vector<Keyframe> truth = TrueKeyframes(*exact_simulator_, exact_->imu, kPhaseS);
  const sensors::Calibration true_calibration = exact_simulator_->true_calibration();
  const auto residuals = [&](double compliance) {
    std::vector<Keyframe> keyframes = truth;
    sensors::Calibration calibration = true_calibration;
    auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
    KeyframeWheelOptions options;
    options.factor.lateral_sigma_m_s = kStraightSlipMS;
    options.cornering_compliance_rad_per_m_s2 = compliance;
    options.max_turning_axis_error_deg = 0.0;  // about V's up axis
    options.loss = factors::LossOptions();     // plain least squares: raw whitened rows
    EXPECT_EQ(AddWheelFactors(problem.get(), exact_->imu.samples, exact_->wheel, &keyframes,
                              &calibration, options),
              static_cast<int>(truth.size()));
    std::vector<double> r;
    problem->Evaluate(ceres::Problem::EvaluateOptions(), nullptr, &r, nullptr, nullptr);
    return r;
  };
  constexpr double kCompliance = 0.3 * kDegToRad;
  const std::vector<double> straight = residuals(0.0);
  const std::vector<double> turning = residuals(kCompliance);
  ASSERT_EQ(straight.size(), 4 * truth.size());
  ASSERT_EQ(turning.size(), straight.size());
  const double s0 = kStraightSlipMS;
  const Eigen::Vector3d up_I = true_calibration.q_I_V * Eigen::Vector3d::UnitZ();
  const sensors::ImuSamples& imu = exact_->imu.samples;
  double largest_slip_m_s = 0.0;
  int checked = 0;
  for (size_t k = 0; k < truth.size(); ++k) {
    for (size_t row : {0, 1, 3}) EXPECT_EQ(turning[4 * k + row], straight[4 * k + row]);
    // The gyro interpolated at the keyframe, as the rows take it (no mean over a span).
    const auto after = std::lower_bound(
        imu.begin(), imu.end(), truth[k].t_ns,
        [](const sensors::ImuSample& sample, int64_t t_ns) { return sample.t_ns < t_ns; });
    ASSERT_TRUE(after != imu.begin() && after != imu.end());
    const auto before = after - 1;
    const double s = static_cast<double>(truth[k].t_ns - before->t_ns) /
                     static_cast<double>(after->t_ns - before->t_ns);
    const double omega = ((1.0 - s) * before->gyro_rad_s + s * after->gyro_rad_s).dot(up_I);
    const double slip_m_s = CorneringSlipMS(kCompliance, truth[k].v_W_I.norm(), omega);
    largest_slip_m_s = std::max(largest_slip_m_s, slip_m_s);
    if (std::abs(straight[4 * k + 2]) < 1e-6) continue;  // a row too small to compare
    EXPECT_NEAR(turning[4 * k + 2] * std::hypot(s0, slip_m_s) / (straight[4 * k + 2] * s0), 1.0,
                1e-6)
        << k;
    ++checked;
  }
  EXPECT_GT(checked, static_cast<int>(truth.size()) / 2);
  EXPECT_GT(largest_slip_m_s, 2.0 * s0);  // the drive's turns take the term
  EXPECT_EQ(CorneringSlipMS(kCompliance, 10.0, -0.2), CorneringSlipMS(kCompliance, 10.0, 0.2));
}

// Keyframes whose positions the odometry lost: true orientations turned by 30 deg about the
// vertical and every position and velocity zeroed. The fitted antenna tracks (Eq. K7) put them
// back, through the simulator's multipath outliers and its outages (bridged), and the heading
// of the track against the vehicle's forward axis (Eq. K8) undoes the 30 deg.
TEST_F(KeyframeSensorFactorsTest, PlacesKeyframesOnTheGnssTrack) {
  const std::vector<Keyframe> truth = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
  std::vector<Keyframe> keyframes = truth;
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(30.0 * kDegToRad, Eigen::Vector3d::UnitZ()));
  for (Keyframe& kf : keyframes) {
    kf.q_W_I = turn * kf.q_W_I;
    kf.p_W_I.setZero();
    kf.v_W_I.setZero();
  }
  const sensors::Calibration& c = noisy_simulator_->true_calibration();
  const GnssPlacement placement = PlaceKeyframesOnGnss(
      &keyframes, noisy_->gnss.fixes, Converter(*noisy_simulator_), c.p_I_A, c.q_I_V);
  // Bridged keyframes lie in the outages, interpolated across curves: their positions and
  // velocities only start the solve that follows (gnss_inertial_keyframes.h).
  ASSERT_EQ(placement.placed.size(), keyframes.size());
  double max_p_m = 0.0, max_v_m_s = 0.0, max_rotation_deg = 0.0, sum_p_m2 = 0.0;
  for (size_t k = 0; k < keyframes.size(); ++k) {
    max_rotation_deg =
        std::max(max_rotation_deg,
                 geometry::AngularDistance(keyframes[k].q_W_I, truth[k].q_W_I) * kRadToDeg);
    if (!placement.placed[k]) continue;
    const double p_m = (keyframes[k].p_W_I - truth[k].p_W_I).norm();
    sum_p_m2 += p_m * p_m;
    max_p_m = std::max(max_p_m, p_m);
    max_v_m_s = std::max(max_v_m_s, (keyframes[k].v_W_I - truth[k].v_W_I).norm());
  }
  const double rms_p_m = std::sqrt(sum_p_m2 / static_cast<double>(placement.num_placed));
  std::cout << placement.num_placed << " placed, " << placement.num_bridged << " bridged, "
            << placement.num_headings << " headings (RMS " << placement.heading_rms_rad * kRadToDeg
            << " deg); yaw " << placement.yaw_rad * kRadToDeg
            << " deg; errors on the placed: position max " << max_p_m << " m (RMS " << rms_p_m
            << "), velocity max " << max_v_m_s << " m/s, rotation max " << max_rotation_deg
            << " deg\n";
  EXPECT_GT(placement.num_bridged, 0);  // the outages
  EXPECT_GT(placement.num_headings, 100);
  EXPECT_NEAR(placement.yaw_rad * kRadToDeg, -30.0, 0.5);
  EXPECT_LT(max_rotation_deg, 0.5);
  // Start values for the GNSS-inertial solve (measured: 4.3 cm RMS, 0.11 m and 0.51 m/s at
  // most, the largest where the car enters the roundabout: a quadratic over 2 s of track).
  EXPECT_LT(rms_p_m, 0.1);
  EXPECT_LT(max_p_m, 0.3);
  EXPECT_LT(max_v_m_s, 1.0);
}

// Too few fixes around any keyframe: refused with a message.
TEST_F(KeyframeSensorFactorsTest, PlacementNeedsFixesAroundTheKeyframes) {
  std::vector<Keyframe> keyframes = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
  const sensors::GnssFixes few(noisy_->gnss.fixes.begin(), noisy_->gnss.fixes.begin() + 3);
  const sensors::Calibration& c = noisy_simulator_->true_calibration();
  EXPECT_THROW(
      PlaceKeyframesOnGnss(&keyframes, few, Converter(*noisy_simulator_), c.p_I_A, c.q_I_V), Error);
}

// A quaternion block that Ceres would add as a Euclidean 4-vector is refused.
TEST_F(KeyframeSensorFactorsTest, QuaternionBlocksNeedTheirManifold) {
  std::vector<Keyframe> keyframes = TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS);
  sensors::Calibration calibration = noisy_simulator_->nominal_calibration();
  ceres::Problem problem;
  EXPECT_THROW(
      AddWheelFactors(&problem, noisy_->imu.samples, noisy_->wheel, &keyframes, &calibration),
      Error);
  EXPECT_THROW(AddGnssFactors(&problem, noisy_->imu.samples, noisy_->gnss.fixes,
                              Converter(*noisy_simulator_), &keyframes, &calibration),
               Error);
  EXPECT_EQ(problem.NumResidualBlocks(), 0);
}

// The lever arm from the nominal guess (about 3 cm per axis off) with the simulator's
// multipath outliers (3-15 m) in the fixes, and outages skipped, under the Cauchy loss.
TEST_F(KeyframeSensorFactorsTest, GnssLeverArmWithCauchyLoss) {
  int outliers = 0;
  for (bool is_outlier : noisy_->gnss.is_outlier) outliers += is_outlier;
  ASSERT_GT(outliers, 0);
  double outage_s = 0.0;
  for (const auto& [begin_s, end_s] : noisy_->gnss.outages_s) outage_s += end_s - begin_s;
  const int num_keyframes =
      static_cast<int>(TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS).size());

  int added = 0;
  const Eigen::Vector3d error_m = LeverArmError({factors::RobustLoss::kCauchy, 3.0}, &added);
  std::cout << added << " of " << num_keyframes << " keyframes with a fix (" << outage_s
            << " s of outages), " << outliers << " outlier fixes; lever-arm error "
            << error_m.transpose() << " m (norm " << error_m.norm() << ")\n";
  // Keyframes within an outage (plus one fix period at its ends) get no factor.
  EXPECT_LE(added, num_keyframes - static_cast<int>(outage_s / kKeyframeSpacingS) + 2);
  EXPECT_GE(added, num_keyframes - static_cast<int>(outage_s / kKeyframeSpacingS) - 4);
  EXPECT_LT(error_m.norm(), 0.01);  // measured 4.5 mm
}

// noise_scale divides each GNSS row by its axis group's scale (two horizontal rows, then the
// vertical one, per fix), on the fixes interpolated to keyframes every 0.2 s, on the nearest
// fixes of keyframes every 0.1 s (which would share them) and of the path with a clock offset
// alike.
TEST_F(KeyframeSensorFactorsTest, GnssNoiseScaleWidensEachAxisGroupsSigma) {
  enum class Rows { kInterpolated, kShared, kClock };
  const auto rows = [&](const GnssStdScale& scale, Rows path) {
    std::vector<Keyframe> keyframes;
    for (const Keyframe& kf : TrueKeyframes(*noisy_simulator_, noisy_->imu, kPhaseS)) {
      if (path != Rows::kInterpolated || keyframes.empty() ||
          kf.t_ns - keyframes.back().t_ns > SecondsToNs(0.15)) {
        keyframes.push_back(kf);
      }
    }
    sensors::Calibration calibration = noisy_simulator_->nominal_calibration();
    auto problem = ProblemWithConstantKeyframes(&keyframes, &calibration);
    KeyframeGnssOptions options;
    options.noise_scale = scale;
    options.estimate_time_offset = path == Rows::kClock;
    AddGnssFactors(problem.get(), noisy_->imu.samples, noisy_->gnss.fixes,
                   Converter(*noisy_simulator_), &keyframes, &calibration, options);
    std::vector<double> residuals;
    ceres::Problem::EvaluateOptions evaluate;
    evaluate.apply_loss_function = false;
    problem->Evaluate(evaluate, nullptr, &residuals, nullptr, nullptr);
    return residuals;
  };
  for (const Rows path : {Rows::kInterpolated, Rows::kShared, Rows::kClock}) {
    SCOPED_TRACE(path == Rows::kClock    ? "with a clock offset"
                 : path == Rows::kShared ? "shared fixes"
                                         : "interpolated");
    const std::vector<double> stated = rows({}, path);
    const std::vector<double> scaled = rows({4.0, 2.0}, path);
    ASSERT_EQ(scaled.size(), stated.size());
    ASSERT_GT(stated.size(), 100u);
    ASSERT_EQ(stated.size() % 3, 0u);
    for (size_t i = 0; i < stated.size(); ++i) {
      EXPECT_NEAR(scaled[i], stated[i] / (i % 3 == 2 ? 2.0 : 4.0), 1e-12) << i;
    }
  }
  for (const GnssStdScale bad : {GnssStdScale{0.0, 1.0}, GnssStdScale{1.0, -1.0},
                                 GnssStdScale{std::numeric_limits<double>::infinity(), 1.0}}) {
    EXPECT_THROW(rows(bad, Rows::kInterpolated), Error);
  }
}

// Without a robust loss the same outliers pull the lever arm far off.
TEST_F(KeyframeSensorFactorsTest, GnssOutliersDamageTheLeverArmWithoutLoss) {
  int added = 0;
  const Eigen::Vector3d robust_m = LeverArmError({factors::RobustLoss::kCauchy, 3.0}, &added);
  const Eigen::Vector3d plain_m = LeverArmError({factors::RobustLoss::kNone, 1.0}, &added);
  std::cout << "lever-arm error without loss " << plain_m.transpose() << " m (norm "
            << plain_m.norm() << "), with Cauchy " << robust_m.norm() << " m\n";
  EXPECT_GT(plain_m.norm(), 0.1);  // measured 0.180 m, against 4.5 mm
  EXPECT_GT(plain_m.norm(), 10.0 * robust_m.norm());
}

// A known yaw and shift applied to the true keyframes is undone by the alignment to
// noise-free fixes (keyframes on fix stamps: no interpolation error).
TEST_F(KeyframeSensorFactorsTest, AlignmentRecoversKnownYawAndShift) {
  const std::vector<Keyframe> truth = TrueKeyframes(*exact_simulator_, exact_->imu, 0.0);
  const double yaw_rad = 40.0 * kDegToRad;
  const Eigen::Vector3d shift_m(250.0, -80.0, 2.5);
  const Eigen::Quaterniond q_z(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()));
  std::vector<Keyframe> keyframes = truth;
  for (Keyframe& kf : keyframes) {
    kf.q_W_I = q_z * kf.q_W_I;
    kf.p_W_I = q_z * kf.p_W_I + shift_m;
    kf.v_W_I = q_z * kf.v_W_I;
  }
  const GnssAlignment alignment =
      AlignKeyframesToGnss(&keyframes, exact_->gnss.fixes, Converter(*exact_simulator_),
                           exact_simulator_->true_calibration().p_I_A);
  double max_position_m = 0.0, max_rotation_rad = 0.0, max_velocity_m_s = 0.0;
  for (size_t k = 0; k < truth.size(); ++k) {
    max_position_m = std::max(max_position_m, (keyframes[k].p_W_I - truth[k].p_W_I).norm());
    max_rotation_rad =
        std::max(max_rotation_rad, geometry::AngularDistance(keyframes[k].q_W_I, truth[k].q_W_I));
    max_velocity_m_s = std::max(max_velocity_m_s, (keyframes[k].v_W_I - truth[k].v_W_I).norm());
  }
  std::cout << alignment.num_pairs << " pairs, rms " << alignment.rms_m << " m; max error "
            << max_position_m << " m, " << max_rotation_rad << " rad, " << max_velocity_m_s
            << " m/s\n";
  EXPECT_EQ(alignment.num_inliers, alignment.num_pairs);
  EXPECT_LT(alignment.num_pairs, static_cast<int>(truth.size()));  // outages skipped
  EXPECT_NEAR(alignment.yaw_rad, -yaw_rad, 1e-9);
  // Measured: 1.1e-9 m RMS, 1.7e-10 m, 4.6e-13 rad, 5.6e-12 m/s (geodetic round trip).
  EXPECT_LT(alignment.rms_m, 1e-8);
  EXPECT_LT(max_position_m, 1e-8);
  EXPECT_LT(max_rotation_rad, 1e-10);
  EXPECT_LT(max_velocity_m_s, 1e-8);
}

// Fixes stamped 0.2 s early (a fix stamped t taken at IMU time t + 0.2 s) pair with the wrong
// keyframe positions, the drive's speed times the offset apart; on the IMU clock
// (FixesOnImuClock) the alignment is exact again.
TEST_F(KeyframeSensorFactorsTest, AlignmentTakesTheFixesOnTheImuClock) {
  const std::vector<Keyframe> truth = TrueKeyframes(*exact_simulator_, exact_->imu, 0.0);
  constexpr double kOffsetS = 0.2;
  sensors::GnssFixes early = exact_->gnss.fixes;
  for (sensors::GnssFix& fix : early) fix.t_ns -= SecondsToNs(kOffsetS);
  const Eigen::Vector3d& p_I_A = exact_simulator_->true_calibration().p_I_A;
  std::vector<Keyframe> as_logged = truth;
  const GnssAlignment paired_as_logged =
      AlignKeyframesToGnss(&as_logged, early, Converter(*exact_simulator_), p_I_A);
  std::vector<Keyframe> on_imu_clock = truth;
  const GnssAlignment paired_on_imu_clock = AlignKeyframesToGnss(
      &on_imu_clock, FixesOnImuClock(early, kOffsetS), Converter(*exact_simulator_), p_I_A);
  double mean_speed_m_s = 0.0;
  for (const Keyframe& kf : truth) mean_speed_m_s += kf.v_W_I.norm() / truth.size();
  std::cout << "rms " << paired_as_logged.rms_m << " m as logged, " << paired_on_imu_clock.rms_m
            << " m on the IMU clock; mean speed " << mean_speed_m_s << " m/s\n";
  EXPECT_GT(paired_as_logged.rms_m, 0.3 * kOffsetS * mean_speed_m_s);
  EXPECT_LT(paired_on_imu_clock.rms_m, 1e-6);
  for (size_t k = 0; k < truth.size(); ++k) {
    ASSERT_LT((on_imu_clock[k].p_W_I - truth[k].p_W_I).norm(), 1e-6) << k;
  }
  EXPECT_THROW(FixesOnImuClock(early, std::nan("")), Error);
}

// A gap option beyond 1e9 s is refused: in nanoseconds it passed int64 and wrapped to a
// negative gap, which paired nothing, without a word.
TEST_F(KeyframeSensorFactorsTest, AGapBeyondAnyLogIsRefused) {
  std::vector<Keyframe> keyframes = TrueKeyframes(*exact_simulator_, exact_->imu, 0.0);
  // 0 is the default (the gap from the fixes' rate); a negative gap is refused too.
  for (const auto& [gap_s, message] : std::vector<std::pair<double, std::string>>{
           {1e12, "max_fix_gap_s must be a positive number of seconds up to 1e9"},
           {-0.1,
            "max_fix_gap_s must be 0 (from the stamps, Eq. T1) or a positive number of "
            "seconds, got -0.1"}}) {
    GnssAlignmentOptions options;
    options.max_fix_gap_s = gap_s;
    try {
      AlignKeyframesToGnss(&keyframes, exact_->gnss.fixes, Converter(*exact_simulator_),
                           exact_simulator_->true_calibration().p_I_A, options);
      ADD_FAILURE() << "a gap of " << gap_s << " s was taken";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  }
}

// On the noisy fixes with multipath outliers the refits drop the outliers: the alignment
// is as good as the fix noise allows.
TEST_F(KeyframeSensorFactorsTest, AlignmentRejectsMultipathOutliers) {
  const std::vector<Keyframe> truth = TrueKeyframes(*noisy_simulator_, noisy_->imu, 0.0);
  const double yaw_rad = -120.0 * kDegToRad;
  const Eigen::Vector3d shift_m(-30.0, 400.0, -1.0);
  const Eigen::Quaterniond q_z(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()));
  std::vector<Keyframe> keyframes = truth;
  for (Keyframe& kf : keyframes) {
    kf.q_W_I = q_z * kf.q_W_I;
    kf.p_W_I = q_z * kf.p_W_I + shift_m;
    kf.v_W_I = q_z * kf.v_W_I;
  }
  const GnssAlignment alignment =
      AlignKeyframesToGnss(&keyframes, noisy_->gnss.fixes, Converter(*noisy_simulator_),
                           noisy_simulator_->true_calibration().p_I_A);
  double max_position_m = 0.0, max_rotation_deg = 0.0;
  for (size_t k = 0; k < truth.size(); ++k) {
    max_position_m = std::max(max_position_m, (keyframes[k].p_W_I - truth[k].p_W_I).norm());
    max_rotation_deg =
        std::max(max_rotation_deg,
                 geometry::AngularDistance(keyframes[k].q_W_I, truth[k].q_W_I) * kRadToDeg);
  }
  std::cout << alignment.num_inliers << " of " << alignment.num_pairs << " pairs kept, rms "
            << alignment.rms_m << " m; max error " << max_position_m << " m, " << max_rotation_deg
            << " deg\n";
  // Keyframes sit on fix stamps: exactly the pairs of flagged fixes are dropped.
  int flagged = 0;
  for (size_t i = 0; i < noisy_->gnss.fixes.size(); ++i) {
    const int64_t t_ns = noisy_->gnss.fixes[i].t_ns;
    flagged += noisy_->gnss.is_outlier[i] &&
               std::any_of(truth.begin(), truth.end(),
                           [t_ns](const Keyframe& kf) { return kf.t_ns == t_ns; });
  }
  ASSERT_GT(flagged, 0);
  EXPECT_EQ(alignment.num_pairs - alignment.num_inliers, flagged);
  // The 3-D fix noise (3/3/6 cm scaled by 1-2) alone has an RMS of about 0.11 m; measured
  // 0.119 m RMS with 5 of 210 pairs dropped, poses within 5.9 mm and 0.0017 deg.
  EXPECT_LT(alignment.rms_m, 0.15);
  EXPECT_LT(max_position_m, 0.02);
  EXPECT_LT(max_rotation_deg, 0.01);
}

// A slow drift left after the rigid alignment (here 5, -3 and 1 cm/s, 1.5 m over the drive)
// comes out of the positions (Eq. K5b), to the fixes' noise, through the outages and at the
// ends (the windows' lines), with the track's shape over 4 s kept to centimetres; attitudes
// and velocities stay. Measured: 2.9 cm inside, 5.3 cm at the ends, 4 s steps within 6.3 cm.
TEST_F(KeyframeSensorFactorsTest, OdometryDriftComesOutOfThePositions) {
  const std::vector<Keyframe> truth = TrueKeyframes(*noisy_simulator_, noisy_->imu, 0.0);
  const Eigen::Vector3d rate_m_s(0.05, -0.03, 0.01);
  const int64_t t0 = truth.front().t_ns;
  std::vector<Keyframe> keyframes = truth;
  for (Keyframe& kf : keyframes) kf.p_W_I += rate_m_s * NsToSeconds(kf.t_ns - t0);
  const OdometryDriftOptions options;
  const OdometryDrift drift =
      RemoveOdometryDrift(&keyframes, noisy_->gnss.fixes, Converter(*noisy_simulator_),
                          noisy_simulator_->true_calibration().p_I_A, options);
  const double span_s = NsToSeconds(truth.back().t_ns - t0);
  double max_interior_m = 0.0, max_m = 0.0, max_shape_m = 0.0;
  for (size_t k = 0; k < truth.size(); ++k) {
    const double t_s = NsToSeconds(truth[k].t_ns - t0);
    const double error_m = (keyframes[k].p_W_I - truth[k].p_W_I).norm();
    max_m = std::max(max_m, error_m);
    if (t_s > options.half_window_s && t_s < span_s - options.half_window_s) {
      max_interior_m = std::max(max_interior_m, error_m);
    }
    if (k >= 40) {  // 4 s before
      const Eigen::Vector3d step = keyframes[k].p_W_I - keyframes[k - 40].p_W_I;
      max_shape_m = std::max(max_shape_m, (step - (truth[k].p_W_I - truth[k - 40].p_W_I)).norm());
    }
    EXPECT_EQ(keyframes[k].q_W_I.coeffs(), truth[k].q_W_I.coeffs());
    EXPECT_EQ(keyframes[k].v_W_I, truth[k].v_W_I);
  }
  std::cout << drift.num_pairs << " pairs, median " << drift.median_before_m << " -> "
            << drift.median_after_m << " m; error max " << max_m << " m, interior "
            << max_interior_m << " m; 4 s steps within " << max_shape_m << " m\n";
  EXPECT_GT(drift.median_before_m, 0.5);
  EXPECT_LT(drift.median_after_m, 0.12);  // the fixes' own noise: 3/3/6 cm scaled by 1-2
  EXPECT_LT(max_interior_m, 0.05);
  EXPECT_LT(max_m, 0.08);
  EXPECT_LT(max_shape_m, 0.1);
}

TEST_F(KeyframeSensorFactorsTest, OdometryDriftNeedsAWindowOfPairs) {
  const std::vector<Keyframe> truth = TrueKeyframes(*noisy_simulator_, noisy_->imu, 0.0);
  std::vector<Keyframe> keyframes = truth;
  OdometryDriftOptions options;
  options.min_pairs = 100000;
  const OdometryDrift drift =
      RemoveOdometryDrift(&keyframes, noisy_->gnss.fixes, Converter(*noisy_simulator_),
                          noisy_simulator_->true_calibration().p_I_A, options);
  EXPECT_EQ(drift.max_correction_m, 0.0);
  EXPECT_EQ(drift.median_after_m, drift.median_before_m);
  for (size_t k = 0; k < truth.size(); ++k) EXPECT_EQ(keyframes[k].p_W_I, truth[k].p_W_I);
  options.half_window_s = 0.0;
  EXPECT_THROW(RemoveOdometryDrift(&keyframes, noisy_->gnss.fixes, Converter(*noisy_simulator_),
                                   noisy_simulator_->true_calibration().p_I_A, options),
               Error);
}

// A slow platform (issue: a skid-steer robot at up to 1 m/s with 1 m fixes at 2.5 Hz): speed_m_s
// along a heading that turns at turn_rate_rad_s from 40 deg, for duration_s. The fixes carry
// seeded noise of their 1 m sigma; the keyframes (every 0.4 s) point their vehicle x axis
// (q_I_V = I) along the true heading minus 30 deg, as a gyro-propagated start would, so the yaw
// to find is +30 deg.
struct SlowPlatform {
  sensors::GnssFixes fixes;
  std::vector<Keyframe> keyframes;
  sensors::EnuConverter enu{49.0, 8.4, 110.0};
};

SlowPlatform SlowPlatformLog(double speed_m_s, double turn_rate_rad_s, double duration_s) {
  SlowPlatform log;
  std::mt19937_64 random(11);
  std::normal_distribution<double> noise(0.0, 1.0);
  const int64_t start_ns = 1'700'000'000'000'000'000;
  const auto heading = [&](double t_s) { return 40.0 * kDegToRad + turn_rate_rad_s * t_s; };
  const auto position = [&](double t_s) {  // the integral of the speed along the heading
    if (turn_rate_rad_s == 0.0) {
      return Eigen::Vector3d(speed_m_s * t_s * std::cos(heading(0)),
                             speed_m_s * t_s * std::sin(heading(0)), 0.0);
    }
    const double r = speed_m_s / turn_rate_rad_s;
    return Eigen::Vector3d(r * (std::sin(heading(t_s)) - std::sin(heading(0))),
                           -r * (std::cos(heading(t_s)) - std::cos(heading(0))), 0.0);
  };
  for (double t_s = 0.0; t_s <= duration_s; t_s += 0.4) {
    sensors::GnssFix fix;
    fix.t_ns = start_ns + SecondsToNs(t_s);
    fix.std_enu_m = Eigen::Vector3d(1.0, 1.0, 2.0);
    const Eigen::Vector3d p = position(t_s) + Eigen::Vector3d(noise(random), noise(random), 0.0);
    const Eigen::Vector3d lla = log.enu.ToGeodetic(p);
    fix.lat_deg = lla.x();
    fix.lon_deg = lla.y();
    fix.alt_m = lla.z();
    log.fixes.push_back(fix);
  }
  for (double t_s = 3.0; t_s <= duration_s - 3.0; t_s += 0.4) {
    Keyframe kf;
    kf.t_ns = start_ns + SecondsToNs(t_s + 0.13);
    kf.q_W_I = Eigen::AngleAxisd(heading(t_s + 0.13) - 30.0 * kDegToRad, Eigen::Vector3d::UnitZ());
    log.keyframes.push_back(kf);
  }
  return log;
}

// 1 m/s with 1 m fixes: over +-5 s the fitted velocity's sigma (Eq. K10) is about 0.07 m/s, so
// nearly every keyframe's heading stands out of it by more than 5 sigma and gives the yaw.
TEST(PlaceKeyframesOnGnss, ASlowPlatformGetsHeadingsOverAWideWindow) {
  SlowPlatform log = SlowPlatformLog(1.0, 0.02, 120.0);
  GnssPlacementOptions options;
  options.half_width_s = 5.0;
  const GnssPlacement placement =
      PlaceKeyframesOnGnss(&log.keyframes, log.fixes, log.enu, Eigen::Vector3d::Zero(),
                           Eigen::Quaterniond::Identity(), options);
  std::cout << placement.num_headings << " of " << log.keyframes.size()
            << " keyframes give a heading; yaw " << placement.yaw_rad * kRadToDeg << " deg\n";
  EXPECT_FALSE(placement.yaw_from_track_geometry);
  EXPECT_GT(placement.num_headings, static_cast<int>(log.keyframes.size()) * 9 / 10);
  EXPECT_NEAR(placement.yaw_rad * kRadToDeg, 30.0, 2.0);
}

// The same platform with the +-1 s window of a 10 Hz receiver: the velocity's sigma (about
// 0.8 m/s) hides the 1 m/s, so no keyframe gives a heading, and the yaw comes from the whole
// track's travel against the keyframes' forward axes (Eq. K11).
TEST(PlaceKeyframesOnGnss, ASlowPlatformGetsTheYawFromTheTrackGeometry) {
  SlowPlatform log = SlowPlatformLog(1.0, 0.02, 120.0);
  const GnssPlacement placement = PlaceKeyframesOnGnss(
      &log.keyframes, log.fixes, log.enu, Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
  std::cout << "yaw from the track geometry: " << placement.yaw_rad * kRadToDeg << " deg\n";
  EXPECT_TRUE(placement.yaw_from_track_geometry);
  EXPECT_EQ(std::count(placement.heading.begin(), placement.heading.end(), true), 0);
  EXPECT_NEAR(placement.yaw_rad * kRadToDeg, 30.0, 2.0);
}

// The platform drives 60 s forward at 1 m/s, then 40 s backwards, facing the same way; its
// keyframes (every 0.4 s, at times_s) point their vehicle x axis 30 deg right of it, turned
// further by a gyro's yaw drifting at drift_rad_s.
SlowPlatform ReversingPlatformLog(double drift_rad_s, std::vector<double>* times_s) {
  SlowPlatform log;
  std::mt19937_64 random(12);
  std::normal_distribution<double> noise(0.0, 1.0);
  const int64_t start_ns = 1'700'000'000'000'000'000;
  const double heading_rad = 40.0 * kDegToRad;
  const auto along_m = [](double t_s) { return t_s <= 60.0 ? t_s : 120.0 - t_s; };
  for (double t_s = 0.0; t_s <= 100.0; t_s += 0.4) {
    sensors::GnssFix fix;
    fix.t_ns = start_ns + SecondsToNs(t_s);
    fix.std_enu_m = Eigen::Vector3d(1.0, 1.0, 2.0);
    const Eigen::Vector3d p =
        along_m(t_s) * Eigen::Vector3d(std::cos(heading_rad), std::sin(heading_rad), 0.0) +
        Eigen::Vector3d(noise(random), noise(random), 0.0);
    const Eigen::Vector3d lla = log.enu.ToGeodetic(p);
    fix.lat_deg = lla.x();
    fix.lon_deg = lla.y();
    fix.alt_m = lla.z();
    log.fixes.push_back(fix);
  }
  for (double t_s = 6.0; t_s <= 94.0; t_s += 0.4) {
    Keyframe kf;
    kf.t_ns = start_ns + SecondsToNs(t_s + 0.13);
    kf.q_W_I = Eigen::AngleAxisd(heading_rad - 30.0 * kDegToRad + drift_rad_s * (t_s + 0.13),
                                 Eigen::Vector3d::UnitZ());
    log.keyframes.push_back(kf);
    times_s->push_back(t_s + 0.13);
  }
  return log;
}

// The reversing keyframes' headings lie 180 deg from the others: left out of the yaw, they are
// not flagged either, so the GNSS-inertial rebuild does not turn them onto their velocity
// (Eq. K9), which started them 180 deg off before.
TEST(PlaceKeyframesOnGnss, AReversingPlatformsHeadingsStayOutOfTheYaw) {
  std::vector<double> times_s;
  SlowPlatform log = ReversingPlatformLog(0.0, &times_s);
  GnssPlacementOptions options;
  options.half_width_s = 5.0;
  const GnssPlacement placement =
      PlaceKeyframesOnGnss(&log.keyframes, log.fixes, log.enu, Eigen::Vector3d::Zero(),
                           Eigen::Quaterniond::Identity(), options);
  EXPECT_NEAR(placement.yaw_rad * kRadToDeg, 30.0, 2.0);
  EXPECT_EQ(std::count(placement.heading.begin(), placement.heading.end(), true),
            placement.num_headings);
  int reversing = 0;
  for (size_t k = 0; k < times_s.size(); ++k) {
    if (times_s[k] < 66.0) continue;
    ++reversing;
    EXPECT_FALSE(placement.heading[k]) << "reversing at " << times_s[k] << " s";
  }
  EXPECT_GT(reversing, 60);
}

// The same platform with keyframes whose gyro yaw drifts at 5e-3 rad/s (0.44 rad over the
// log): each heading is judged against those within 5 s (Eq. K8), so the forward ones all stay
// and the reversing ones stay out. Judged against the mean of the whole log, only those within
// 0.2 rad of it stayed: 82 of the 120 forward keyframes.
TEST(PlaceKeyframesOnGnss, ADriftingGyroKeepsTheForwardHeadings) {
  std::vector<double> times_s;
  SlowPlatform log = ReversingPlatformLog(5e-3, &times_s);
  GnssPlacementOptions options;
  options.half_width_s = 5.0;
  const GnssPlacement placement =
      PlaceKeyframesOnGnss(&log.keyframes, log.fixes, log.enu, Eigen::Vector3d::Zero(),
                           Eigen::Quaterniond::Identity(), options);
  int forward = 0, forward_kept = 0, reversing_kept = 0;
  for (size_t k = 0; k < times_s.size(); ++k) {
    if (times_s[k] > 54.0 && times_s[k] < 66.0) continue;  // the turnaround
    const bool reversing = times_s[k] >= 66.0;
    forward += reversing ? 0 : 1;
    (reversing ? reversing_kept : forward_kept) += placement.heading[k] ? 1 : 0;
  }
  std::cout << placement.num_headings << " headings kept: " << forward_kept << " of " << forward
            << " forward, " << reversing_kept << " reversing; RMS about those around them "
            << placement.heading_rms_rad * kRadToDeg << " deg\n";
  EXPECT_EQ(std::count(placement.heading.begin(), placement.heading.end(), true),
            placement.num_headings);
  EXPECT_GT(forward, 100);
  EXPECT_GT(forward_kept, forward * 95 / 100);
  EXPECT_EQ(reversing_kept, 0);
}

// A slow platform's receiver silent for its first 20 s and for 150 s in the middle: the
// keyframes there have no track of their own and are bridged from the nearest placed ones,
// interpolated between them in time, or moved at the first placed one's velocity before it.
TEST(PlaceKeyframesOnGnss, ALongOutageIsBridgedBetweenItsPlacedNeighbours) {
  SlowPlatform log = SlowPlatformLog(1.0, 0.02, 300.0);
  const int64_t start_ns = log.fixes.front().t_ns;
  const auto silent = [&](int64_t t_ns) {
    const double t_s = NsToSeconds(t_ns - start_ns);
    return t_s < 20.0 || (t_s >= 100.0 && t_s < 250.0);
  };
  log.fixes.erase(std::remove_if(log.fixes.begin(), log.fixes.end(),
                                 [&](const sensors::GnssFix& f) { return silent(f.t_ns); }),
                  log.fixes.end());
  GnssPlacementOptions options;
  options.half_width_s = 5.0;
  const GnssPlacement placement =
      PlaceKeyframesOnGnss(&log.keyframes, log.fixes, log.enu, Eigen::Vector3d::Zero(),
                           Eigen::Quaterniond::Identity(), options);
  const std::vector<Keyframe>& kfs = log.keyframes;
  int bridged = 0, between = 0;
  for (size_t k = 0; k < kfs.size(); ++k) {
    if (placement.placed[k]) continue;
    ++bridged;
    ptrdiff_t b = static_cast<ptrdiff_t>(k), a = static_cast<ptrdiff_t>(k);
    while (b >= 0 && !placement.placed[static_cast<size_t>(b)]) --b;
    while (a < static_cast<ptrdiff_t>(kfs.size()) && !placement.placed[static_cast<size_t>(a)]) ++a;
    ASSERT_TRUE(b >= 0 || a < static_cast<ptrdiff_t>(kfs.size()));
    const Keyframe& kf = kfs[k];
    if (b < 0) {  // before the first placed keyframe
      const Keyframe& first = kfs[static_cast<size_t>(a)];
      EXPECT_EQ(kf.p_W_I, first.p_W_I + first.v_W_I * NsToSeconds(kf.t_ns - first.t_ns)) << k;
      EXPECT_EQ(kf.v_W_I, first.v_W_I) << k;
      continue;
    }
    ASSERT_LT(a, static_cast<ptrdiff_t>(kfs.size()));
    ++between;
    const Keyframe& i = kfs[static_cast<size_t>(b)];
    const Keyframe& j = kfs[static_cast<size_t>(a)];
    const double s = NsToSeconds(kf.t_ns - i.t_ns) / NsToSeconds(j.t_ns - i.t_ns);
    EXPECT_EQ(kf.p_W_I, ((1.0 - s) * i.p_W_I + s * j.p_W_I).eval()) << k;
    EXPECT_EQ(kf.v_W_I, ((1.0 - s) * i.v_W_I + s * j.v_W_I).eval()) << k;
  }
  std::cout << bridged << " bridged keyframes, " << between << " between placed ones\n";
  EXPECT_EQ(bridged, placement.num_bridged);
  EXPECT_GT(between, 350);
  EXPECT_GT(bridged - between, 30);
}

// A standing platform whose fixes alternate between 2 cm and 1 m: the track's velocity is that
// of the 2 cm fixes, as Eq. K10 states. Fitted without their weights it scattered with the 1 m
// fixes while K10 stated the 2 cm ones' sigma, and nearly every keyframe got a heading.
TEST(PlaceKeyframesOnGnss, AStandingPlatformWithMixedFixesGivesNoYaw) {
  SlowPlatform log = SlowPlatformLog(0.0, 0.0, 120.0);
  std::mt19937_64 random(13);
  std::normal_distribution<double> noise(0.0, 1.0);
  for (size_t i = 0; i < log.fixes.size(); ++i) {
    sensors::GnssFix& fix = log.fixes[i];
    const double sigma_m = i % 2 == 0 ? 0.02 : 1.0;
    fix.std_enu_m = Eigen::Vector3d(sigma_m, sigma_m, 2.0);
    const Eigen::Vector3d lla =
        log.enu.ToGeodetic(Eigen::Vector3d(sigma_m * noise(random), sigma_m * noise(random), 0.0));
    fix.lat_deg = lla.x();
    fix.lon_deg = lla.y();
    fix.alt_m = lla.z();
  }
  GnssPlacementOptions options;
  options.half_width_s = 5.0;
  EXPECT_THROW(PlaceKeyframesOnGnss(&log.keyframes, log.fixes, log.enu, Eigen::Vector3d::Zero(),
                                    Eigen::Quaterniond::Identity(), options),
               Error);
}

// A standing platform: no heading stands out of the noise and the track goes nowhere. The
// error says so with the figures.
TEST(PlaceKeyframesOnGnss, AStandingPlatformGivesNoYaw) {
  SlowPlatform log = SlowPlatformLog(0.0, 0.0, 120.0);
  GnssPlacementOptions options;
  options.half_width_s = 5.0;
  try {
    PlaceKeyframesOnGnss(&log.keyframes, log.fixes, log.enu, Eigen::Vector3d::Zero(),
                         Eigen::Quaterniond::Identity(), options);
    FAIL() << "a standing platform gave a yaw";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no heading for the yaw: 0 of"), std::string::npos) << what;
    EXPECT_NE(what.find("move faster than 5.0 sigma of their fitted velocity"), std::string::npos)
        << what;
    EXPECT_NE(what.find("the fixes' median horizontal sigma is 1.00 m"), std::string::npos) << what;
    EXPECT_NE(what.find("too slow or too short"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
