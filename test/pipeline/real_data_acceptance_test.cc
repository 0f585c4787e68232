// The real skid-steer robot (../shared/data/ros1_bags/test1.bag: IMU 30 Hz mounted y-up,
// odometry as speed and yaw rate at 10 Hz stamped about 0.39 s late, GPS 2.5 Hz, at most
// 1 m/s over 395 s) imported and calibrated from problems/skid_steer_imu_odometry_gnss.yaml,
// starting from a mount 10 deg off the launch file's R_V_I = Rz(-90 deg) Rx(+90 deg).
// Checked: the odometry's clock -0.39 +- 0.05 s (t_imu = t_odometry + offset), the odometry
// speed scale in [0.93, 1.00], a run under 30 s, the mount's roll and pitch (from the turns,
// Eq. F27) within 2 deg, the roll reported observable, the antenna within 1.5 m RMS of the
// fixes (the IMU's noise measured from its samples: 37 times the accelerometer's default
// density on this robot). The pitch's rows scatter over the log far beyond their noise model
// (Eq. C8): its sigma, widened to about 1 deg, leaves it held at its prior, and the sigmas
// cover what the log's two halves say apart. Not met: the whole mount within 2 deg of the
// launch file's. Its yaw is not determined by this drive (checked: reported so, held at the
// nominal value, within three of the prior's sigmas). The robot without GPS (test2.bag) is dead
// reckoned and reports what it cannot observe. With the mount or the odometry's clock fixed in
// the problem, the run names what the log contradicts (Eq. C7; the clock's cross-correlation).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/estimation/calibration_fusion.h"
#include "autocal/estimation/gnss_noise.h"
#include "autocal/geometry/so3.h"
#include "autocal/import/import_bag.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/pipeline/online_estimation.h"
#include "autocal/sensors/calibration_blocks.h"
#include "autocal/sensors/gnss_enu.h"
#include "support/fixed_block_warnings.h"
#include "support/test_paths.h"

namespace autocal {
namespace pipeline {
namespace {

io::Dataset Import(const std::filesystem::path& bag) {
  const std::filesystem::path directory = test::OutputDir("dataset") / bag.stem();
  std::filesystem::remove_all(directory);
  import::ImportOptions options;
  options.input = bag.string();
  options.output = directory.string();
  import::ImportBag(options);
  return io::ReadDataset(directory.string());
}

io::Problem Shipped(const std::string& name) {
  return io::ReadProblemYaml(
      (std::filesystem::path(AUTOCAL_SOURCE_DIR) / "problems" / name).string());
}

// R_V_I of the launch file: the IMU's y axis up, its x axis to the right.
Eigen::Quaterniond LaunchFileMount() {
  return Eigen::Quaterniond(Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
}

// test1.bag imported, its nominal mount the launch file's.
io::Dataset SkidSteerFromTheLaunchFileMount() {
  io::Dataset dataset = Import(test::SharedDataDir("ros1_bags") / "test1.bag");
  dataset.sensors.nominal_calibration.q_I_V = LaunchFileMount().conjugate();
  return dataset;
}

// test1.bag imported, its nominal mount 10 deg off the launch file's (about (1, 1, 1)).
io::Dataset SkidSteerFromTenDegreesOff() {
  io::Dataset dataset = Import(test::SharedDataDir("ros1_bags") / "test1.bag");
  const Eigen::Quaterniond ten_degrees_off(
      Eigen::AngleAxisd(10.0 * kDegToRad, Eigen::Vector3d(1.0, 1.0, 1.0).normalized()));
  dataset.sensors.nominal_calibration.q_I_V = (LaunchFileMount() * ten_degrees_off).conjugate();
  return dataset;
}

// Horizontal RMS of the keyframes' antennas against the fixes within 50 ms of them.
double AntennaRmsM(const OfflineCalibrationResult& result, const io::Dataset& dataset) {
  const sensors::EnuConverter enu = sensors::EnuConverter::AtFirstFix(dataset.gnss);
  double sum_m2 = 0.0;
  size_t pairs = 0;
  for (const io::TrajectorySample& s : result.trajectory) {
    const auto fix =
        std::lower_bound(dataset.gnss.begin(), dataset.gnss.end(), s.t_ns,
                         [](const sensors::GnssFix& f, int64_t t) { return f.t_ns < t; });
    if (fix == dataset.gnss.end() || std::abs(fix->t_ns - s.t_ns) > 50'000'000) continue;
    const Eigen::Vector3d antenna = s.T_W_I.p + s.T_W_I.q * result.calibration.value.p_I_A;
    sum_m2 += (antenna - enu.ToEnu(*fix)).head<2>().squaredNorm();
    ++pairs;
  }
  EXPECT_GT(pairs, 100u);
  return std::sqrt(sum_m2 / static_cast<double>(std::max<size_t>(pairs, 1)));
}

// The sigma of one direction of a block after the solve, before any direction was held: as the
// noise model gives it or, with `widened`, as the rows' scatter over the log widens it (Eq. C8).
double SigmaAfterTheSolveDeg(const OfflineCalibrationResult& result, sensors::CalibrationBlockId id,
                             int direction, bool widened) {
  const estimation::CalibrationPosterior& posterior = result.posterior;
  const estimation::BlockCovariance& covariance =
      widened ? posterior.widened : posterior.covariance;
  EXPECT_TRUE(covariance.ok);
  for (size_t b = 0; b < posterior.blocks.size(); ++b) {
    if (posterior.blocks[b].id != id) continue;
    const int row = covariance.offsets[b] + direction;
    return std::sqrt(covariance.matrix(row, row)) * kRadToDeg;
  }
  ADD_FAILURE() << "the block is not estimated";
  return 0.0;
}

TEST(RealDataAcceptance, SkidSteerRobotWithGps) {
  const std::filesystem::path bag = test::SharedDataDir("ros1_bags") / "test1.bag";
  AUTOCAL_REQUIRE_SHARED_DATA(bag);
  const io::Dataset dataset = SkidSteerFromTenDegreesOff();
  const Eigen::Quaterniond q_V_I = LaunchFileMount();

  const auto start = std::chrono::steady_clock::now();
  const OfflineCalibrationResult result =
      CalibrateDataset(dataset, Shipped("skid_steer_imu_odometry_gnss.yaml"));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const sensors::Calibration& c = result.calibration.value;
  const double mount_error_deg =
      geometry::Log(Eigen::Quaterniond(q_V_I * c.q_I_V)).norm() * kRadToDeg;
  const double rms_m = AntennaRmsM(result, dataset);
  const Eigen::Vector3d mount_error_rad = geometry::Log(Eigen::Quaterniond(q_V_I * c.q_I_V));
  std::cout << "mount error about the vehicle's x, y, z: "
            << (mount_error_rad * kRadToDeg).transpose() << " deg\n";
  std::cout << "odometry clock " << c.time_offset_wheel_imu_s << " s, k_v "
            << c.odometry_speed_scale << ", b_eff " << c.effective_track_m << " m, mount "
            << mount_error_deg << " deg off, antenna " << rms_m << " m RMS, " << seconds << " s\n";
  for (const std::string& w : result.warnings) std::cout << "warning: " << w << "\n";
  EXPECT_NEAR(c.time_offset_wheel_imu_s, -0.39, 0.05);
  EXPECT_GE(c.odometry_speed_scale, 0.93);
  EXPECT_LE(c.odometry_speed_scale, 1.00);
  EXPECT_LT(seconds, 30.0);
  EXPECT_LT(rms_m, 1.5);
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::HasSubstr("IMU accelerometer: its samples scatter")));
  // The mount's roll and pitch within 2 deg of the launch file's, from the turns; the pitch's
  // wheel rows scatter 13 times their noise model over the log's stretches (Eq. C8), and its
  // sigma, 0.16 deg as the noise model gives it, is widened to about 1 deg and held at its
  // prior (the log's quarters put it at -1.5, +1.1 and -2.8 deg at 0.3-0.4 deg). Its yaw is not
  // determined by this slow drive: the cost's curvature along it gives a sigma of 8 deg
  // (docs/keyframe_factors.md, "What the planar-rotation rows say about the yaw"), so it is held
  // at the nominal value with the prior's sigma, which covers the 10 deg start. Before that,
  // the solve's own sigma is the cost's curvature with the prior (4.2 deg, the odometry clock
  // held): 3.99 deg from the completed Hessian (docs/calibration.md, Eq. C5), where
  // Gauss-Newton's 2.21 deg counted the velocities' noise.
  const io::PoseBlockInfo& mount = result.calibration.uncertainty.T_I_V;
  ASSERT_TRUE(mount.sigma_rot_deg.has_value());
  ASSERT_EQ(mount.observable.size(), 6u);
  std::cout << "mount sigma (roll, pitch, yaw) " << mount.sigma_rot_deg->transpose() << " deg\n";
  for (int i = 0; i < 2; ++i) EXPECT_LT(std::abs(mount_error_rad[i]) * kRadToDeg, 2.0) << i;
  EXPECT_TRUE(mount.observable[0]);
  EXPECT_FALSE(mount.observable[1]);
  EXPECT_FALSE(mount.observable[2]);
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::StartsWith(
                  "wheel rows: over 16 stretches of the log their share of the mount pitch")));
  EXPECT_LT(SigmaAfterTheSolveDeg(result, sensors::CalibrationBlockId::kVehicleRotation, 1, false),
            0.3);
  EXPECT_GT(SigmaAfterTheSolveDeg(result, sensors::CalibrationBlockId::kVehicleRotation, 1, true),
            0.8);
  EXPECT_THAT(result.warnings, ::testing::Contains(::testing::HasSubstr(
                                   "mount yaw (about the vehicle's up axis): not excited")));
  EXPECT_LT(std::abs(mount_error_rad.z()) * kRadToDeg, 3.0 * mount.sigma_rot_deg->z());
  const double yaw_sigma_after_solve_deg = SigmaAfterTheSolveDeg(
      result, sensors::CalibrationBlockId::kVehicleRotation, 2, false);  // about the vehicle's z
  std::cout << "mount yaw sigma after the solve " << yaw_sigma_after_solve_deg << " deg\n";
  EXPECT_GT(yaw_sigma_after_solve_deg, 3.4);
  EXPECT_LT(yaw_sigma_after_solve_deg, 5.0);
  EXPECT_LT(mount_error_deg, 3.0 * mount.sigma_rot_deg->z());
}

// `dataset`'s samples within the `part`-th of `parts` equal spans of its IMU's time.
io::Dataset PartOf(const io::Dataset& dataset, int part, int parts) {
  const int64_t first = dataset.imu.front().t_ns;
  const int64_t span = dataset.imu.back().t_ns - first;
  const int64_t begin = first + span * part / parts;
  const int64_t end = first + span * (part + 1) / parts;
  io::Dataset out = dataset;
  const auto keep = [&](auto* samples) {
    samples->erase(std::remove_if(samples->begin(), samples->end(),
                                  [&](const auto& s) { return s.t_ns < begin || s.t_ns > end; }),
                   samples->end());
  };
  keep(&out.imu);
  keep(&out.odometry);
  keep(&out.gnss);
  return out;
}

// The largest difference between the two halves' estimates of a direction, in sigmas of the
// difference (each half's sigma after its solve, before any direction is held), and where.
std::pair<double, std::string> LargestDisagreement(const OfflineCalibrationResult& a,
                                                   const OfflineCalibrationResult& b) {
  std::pair<double, std::string> largest{0.0, ""};
  for (size_t i = 0; i < a.posterior.blocks.size(); ++i) {
    const estimation::EstimatedBlock& block = a.posterior.blocks[i];
    for (size_t j = 0; j < b.posterior.blocks.size(); ++j) {
      if (b.posterior.blocks[j].id != block.id) continue;
      const sensors::CalibrationBlockInfo& info = sensors::CalibrationBlock(block.id);
      const Eigen::VectorXd difference = estimation::BlockMinus(
          block, info.const_values(a.posterior.solved), info.const_values(b.posterior.solved));
      for (int d = 0; d < block.size; ++d) {
        const int row_a = a.posterior.widened.offsets[i] + d;
        const int row_b = b.posterior.widened.offsets[j] + d;
        const double z =
            std::abs(difference(d)) / std::sqrt(a.posterior.widened.matrix(row_a, row_a) +
                                                b.posterior.widened.matrix(row_b, row_b));
        if (z > largest.first) largest = {z, block.direction_names[static_cast<size_t>(d)]};
      }
    }
  }
  return largest;
}

// The blocks on which two logs disagree by the several-log test (Eq. M3) at the several-log
// calibration's default p-value of 0.01 over the blocks tested, each with its p-value.
std::vector<std::string> BlocksTheHalvesDisagreeOn(const OfflineCalibrationResult& a,
                                                   const OfflineCalibrationResult& b) {
  const std::vector<estimation::BlockAgreement> agreement =
      estimation::AgreementOfLogs({a.posterior, b.posterior});
  std::vector<std::string> out;
  for (const estimation::BlockAgreement& block : agreement) {
    const double threshold = 0.01 / static_cast<double>(agreement.size());
    std::cout << "  " << sensors::CalibrationBlock(block.id).key << " p " << block.p_value
              << (block.p_value < threshold ? " (differ)" : "") << "\n";
    if (block.p_value < threshold) out.push_back(sensors::CalibrationBlock(block.id).key);
  }
  return out;
}

// Honest sigmas on a real log: its two halves (198 s each), calibrated apart, estimate each
// direction alike within its sigmas (each half's after its solve, before any is held). Without
// the rows' scatter over the log (Eq. C8) the mount pitches stood 15 sigmas apart (+4.0 and
// -1.2 deg, sigma 0.28 and 0.21 deg), the odometry speed scale 11, the antenna's x 9; with it
// the pitch stands at 2.7 sigmas and every direction within 2.7 but two: the antenna's x, which
// both halves leave at the prior's sigma (held), 4.0, and the odometry clock, 4.1 (-0.367 and
// -0.395 s, sigma 5.7 and 4.8 ms: its lag moved by 28 ms between the halves, which no stretch
// of either half shows). Measured with 8 and 32 stretches and at 1 % alike.
// The several-log test (Eq. M3) then finds three of the six blocks different (the mount, p
// 6e-4, the antenna, 3e-4, the odometry clock, 5e-5, against 0.01 / 6) where it found all six
// (p down to 1e-52), and combining the halves (Eq. M1-M2) gives the mount pitch a sigma of
// 0.55 deg, where the noise model alone gives 0.17 deg (the whole log's widened sigma: 1.09
// deg; errors that last longer than a half's stretches stay unseen).
TEST(RealDataAcceptance, SigmasCoverWhatTheLogsHalvesSayApart) {
  AUTOCAL_REQUIRE_SHARED_DATA(test::SharedDataDir("ros1_bags") / "test1.bag");
  const io::Dataset dataset = SkidSteerFromTheLaunchFileMount();
  const io::Problem problem = Shipped("skid_steer_imu_odometry_gnss.yaml");
  for (const int stretches : {16, 0}) {
    OfflineCalibrationOptions options;
    options.scatter_stretches = stretches;
    const OfflineCalibrationResult first =
        CalibrateDataset(PartOf(dataset, 0, 2), problem, options);
    const OfflineCalibrationResult second =
        CalibrateDataset(PartOf(dataset, 1, 2), problem, options);
    const auto [sigmas, direction] = LargestDisagreement(first, second);
    std::cout << "stretches " << stretches << ": the halves differ by at most " << sigmas
              << " sigma (" << direction << ")\n";
    const std::vector<std::string> differ = BlocksTheHalvesDisagreeOn(first, second);
    const estimation::FusedCalibration fused =
        estimation::FuseCalibrationPosteriors({first.posterior, second.posterior});
    ASSERT_TRUE(fused.covariance.ok);
    ASSERT_EQ(fused.blocks.front().id, sensors::CalibrationBlockId::kVehicleRotation);
    const double fused_pitch_sigma_deg = std::sqrt(fused.covariance.matrix(1, 1)) * kRadToDeg;
    std::cout << "  the halves combined (Eq. M1-M2): mount pitch sigma " << fused_pitch_sigma_deg
              << " deg\n";
    if (stretches > 0) {
      EXPECT_LT(sigmas, 5.0) << direction;
      EXPECT_LE(differ.size(), 3u);
      EXPECT_GT(fused_pitch_sigma_deg, 0.4);
    } else {
      EXPECT_GT(sigmas, 10.0) << direction;  // the test sees what Eq. C8 mends
      EXPECT_EQ(differ.size(), 6u);
      EXPECT_LT(fused_pitch_sigma_deg, 0.25);
    }
  }
}

// A problem that fixes the mount at the nominal 10 deg off the launch file's hears, after the
// solve, that the log would move its roll back by about what it is off (the launch file's
// mount, in V: 10 deg about (-1, -1, 1), 5.8 deg on each axis), within the 2 deg the log's own
// estimate keeps to the launch file (docs/calibration.md, Eq. C7): -4.67 deg at a sigma of
// 1.03 deg, 4.5 sigmas, named here from 3. Its sigma is widened by the rows' scatter over the
// log (Eq. C8, at the Gauss-Newton step's residuals; 0.86 deg without), which widens the
// pitch's past half its prior's: the log then does not inform the pitch enough to judge it,
// as it leaves the estimated pitch at its prior. By the noise model alone (no Eq. C8
// anywhere) both are named: -4.56 and -4.48 deg at 0.28 and 0.21 deg. The yaw, which this
// slow drive does not determine, is never judged.
TEST(RealDataAcceptance, SaysWhenTheLogContradictsAFixedMount) {
  const std::filesystem::path bag = test::SharedDataDir("ros1_bags") / "test1.bag";
  AUTOCAL_REQUIRE_SHARED_DATA(bag);
  const io::Dataset dataset = SkidSteerFromTenDegreesOff();
  io::Problem problem = Shipped("skid_steer_imu_odometry_gnss.yaml");
  problem.calibration.T_I_V.rotation.mode = io::BlockMode::kFixed;
  const Eigen::Vector3d off_deg =
      geometry::Log(Eigen::Quaterniond(dataset.sensors.nominal_calibration.q_I_V.conjugate() *
                                       LaunchFileMount().conjugate())) *
      kRadToDeg;
  std::cout << "launch file - nominal mount (deg): " << off_deg.transpose() << "\n";
  for (const int stretches : {16, 0}) {
    OfflineCalibrationOptions options;
    options.max_fixed_block_step_sigmas = 3.0;
    options.scatter_stretches = stretches;
    const std::vector<std::string> warnings =
        test::FixedDirectionWarnings(CalibrateDataset(dataset, problem, options).warnings);
    const auto step_deg = [&](const std::string& direction) {
      const std::optional<test::FixedDirectionStep> named =
          test::StepOfFixedDirection(warnings, direction);
      EXPECT_TRUE(named.has_value()) << direction << " is not named";
      return named ? named->step : 0.0;
    };
    EXPECT_NEAR(step_deg("mount roll (about the vehicle's forward axis)"), off_deg.x(), 2.0);
    if (stretches == 0) {
      EXPECT_NEAR(step_deg("mount pitch (about the vehicle's left axis)"), off_deg.y(), 2.0);
    } else {
      EXPECT_THAT(warnings, ::testing::Not(::testing::Contains(::testing::StartsWith(
                                "mount pitch (about the vehicle's left axis) is fixed"))));
    }
    EXPECT_THAT(warnings, ::testing::Not(::testing::Contains(::testing::StartsWith("mount yaw"))));
  }
}

// test::StepOfFixedDirection, a failure when `direction` is not named.
test::FixedDirectionStep NamedStep(const std::vector<std::string>& warnings,
                                   const std::string& direction) {
  const std::optional<test::FixedDirectionStep> named =
      test::StepOfFixedDirection(test::FixedDirectionWarnings(warnings), direction);
  if (!named) ADD_FAILURE() << direction << " is not named";
  return named.value_or(test::FixedDirectionStep());
}

// The same through the window (docs/sliding_window.md, "Fixed blocks"), the vehicle frame fixed
// (the window estimates its rotation and translation together). The imported log has no
// /tf_static, so its nominal p_I_V is zero; the launch file puts the IMU at (0, -0.3, 0.52) m
// in base_link. With the axle there and the mount 10 deg off, the stream would move the roll
// and pitch towards the launch file's, to where the window's own estimate of the mount takes
// them (as streamed: the result holds the pitch at the prior, Eq. W9), within 3 sigma of the step
// (measured: -4.47 and -3.15 deg, sigma 0.43 and 0.30 deg, for -5.02 and -2.94 deg; the window's
// pitch stays 3 deg from the launch file's, the batch's within 2), not the yaw; with the mount at
// the launch file's and the axle at zero, it would move the axle's height (y, the IMU's up axis) to
// the launch file's (measured: -56.4 cm, sigma 2.3 cm, for -52).
TEST(RealDataAcceptance, SaysWhenTheStreamContradictsAFixedMount) {
  const std::filesystem::path bag = test::SharedDataDir("ros1_bags") / "test1.bag";
  AUTOCAL_REQUIRE_SHARED_DATA(bag);
  io::Problem problem = Shipped("skid_steer_imu_odometry_gnss.yaml");
  problem.calibration.T_I_V.rotation.mode = io::BlockMode::kFixed;
  problem.calibration.T_I_V.translation.mode = io::BlockMode::kFixed;
  const Eigen::Vector3d p_I_V_launch_m =
      LaunchFileMount().conjugate() * -Eigen::Vector3d(0.0, -0.3, 0.52);
  io::Dataset dataset = SkidSteerFromTenDegreesOff();
  ASSERT_EQ(dataset.sensors.nominal_calibration.p_I_V, Eigen::Vector3d::Zero());
  const Eigen::Vector3d off_deg =
      geometry::Log(Eigen::Quaterniond(dataset.sensors.nominal_calibration.q_I_V.conjugate() *
                                       LaunchFileMount().conjugate())) *
      kRadToDeg;

  dataset.sensors.nominal_calibration.p_I_V = p_I_V_launch_m;
  const std::vector<std::string> rotated = EstimateDatasetOnline(dataset, problem).warnings;
  const OnlineEstimationResult mount_estimated =
      EstimateDatasetOnline(dataset, Shipped("skid_steer_imu_odometry_gnss.yaml"));
  const Eigen::Vector3d estimated_deg =
      geometry::Log(
          Eigen::Quaterniond(dataset.sensors.nominal_calibration.q_I_V.conjugate() *
                             mount_estimated.calibration_over_time.back().calibration.q_I_V)) *
      kRadToDeg;
  std::cout << "estimated - nominal (deg): " << estimated_deg.transpose() << ", launch - nominal "
            << off_deg.transpose() << "\n";
  for (int axis : {0, 1}) {
    const char* direction = axis == 0 ? "mount roll (about the vehicle's forward axis)"
                                      : "mount pitch (about the vehicle's left axis)";
    const test::FixedDirectionStep named = NamedStep(rotated, direction);
    EXPECT_GT(named.step / off_deg(axis), 0.0) << direction;  // towards the launch file
    EXPECT_NEAR(named.step, estimated_deg(axis), 3.0 * named.sigma) << direction;
  }
  EXPECT_THAT(rotated, ::testing::Not(::testing::Contains(::testing::StartsWith("mount yaw"))));

  dataset.sensors.nominal_calibration.q_I_V = LaunchFileMount().conjugate();
  dataset.sensors.nominal_calibration.p_I_V.setZero();
  const std::vector<std::string> shifted = EstimateDatasetOnline(dataset, problem).warnings;
  const test::FixedDirectionStep height_cm = NamedStep(shifted, "rear-axle y position (IMU frame)");
  EXPECT_NEAR(height_cm.step, 100.0 * p_I_V_launch_m.y(), 3.0 * height_cm.sigma);
}

// The Husky's odometry lags its gyro by 0.39 s: a problem that keeps the wheel clock fixed at
// the nominal 0 hears so, with where the data put it (docs/calibration.md, "Clocks in the
// offline calibration"); the clock stays where the problem fixed it.
TEST(RealDataAcceptance, SaysWhenAFixedOdometryClockLagsTheImu) {
  const std::filesystem::path bag = test::SharedDataDir("ros1_bags") / "test1.bag";
  AUTOCAL_REQUIRE_SHARED_DATA(bag);
  const io::Dataset dataset = Import(bag);
  io::Problem problem = Shipped("skid_steer_imu_odometry_gnss.yaml");
  problem.calibration.time_offset_wheel_imu_s.mode = io::BlockMode::kFixed;
  const OfflineCalibrationResult result = CalibrateDataset(dataset, problem);
  const std::vector<std::string>& warnings = result.warnings;
  EXPECT_EQ(result.calibration.value.time_offset_wheel_imu_s, 0.0);
  EXPECT_THAT(warnings, ::testing::Contains(::testing::StartsWith(
                            "the wheel-IMU time offset is fixed at 0.0 ms, but the "
                            "cross-correlation of the wheels' yaw rate with the IMU puts it at "
                            "-391")));
}

// autocal_estimate streams the same log: the window without the LiDAR, keyframes at the
// receiver's 0.4 s, the odometry's clock from the cross-correlation (held while streaming), the
// mount from the data when the nominal is no guess.
TEST(RealDataAcceptance, SkidSteerRobotStreamsThroughTheWindow) {
  const std::filesystem::path bag = test::SharedDataDir("ros1_bags") / "test1.bag";
  AUTOCAL_REQUIRE_SHARED_DATA(bag);
  const io::Dataset dataset = SkidSteerFromTenDegreesOff();
  const Eigen::Quaterniond q_V_I = LaunchFileMount();
  const auto start = std::chrono::steady_clock::now();
  const OnlineEstimationResult result =
      EstimateDatasetOnline(dataset, Shipped("skid_steer_imu_odometry_gnss.yaml"));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const sensors::Calibration& c = result.calibration.value;
  const Eigen::Vector3d mount_error_deg =
      geometry::Log(Eigen::Quaterniond(q_V_I * c.q_I_V)) * kRadToDeg;
  OfflineCalibrationResult as_offline;
  as_offline.trajectory = result.trajectory;
  as_offline.calibration = result.calibration;
  const double rms_m = AntennaRmsM(as_offline, dataset);
  std::cout << "online: odometry clock " << c.time_offset_wheel_imu_s << " s, k_v "
            << c.odometry_speed_scale << ", b_eff " << c.effective_track_m << " m, mount error "
            << mount_error_deg.transpose() << " deg, antenna " << rms_m << " m RMS, " << seconds
            << " s, " << result.counters.updates << " keyframes\n";
  for (const std::string& w : result.warnings) std::cout << "warning: " << w << "\n";
  EXPECT_NEAR(c.time_offset_wheel_imu_s, -0.39, 0.05);
  EXPECT_THAT(result.warnings, ::testing::Contains(::testing::HasSubstr("held at")));
  EXPECT_GE(c.odometry_speed_scale, 0.93);
  EXPECT_LE(c.odometry_speed_scale, 1.00);
  EXPECT_LT(seconds, 30.0);
  EXPECT_GT(result.counters.updates, 900);
  // The vertical fixes scatter beyond their stated std over part of the log only (measured: 206
  // fixes scaled, by up to 2.25, the scale at one by the end); what the fixes took is said and
  // recorded though the scale ends at one.
  const std::map<std::string, double>& gnss = result.calibration.residuals.at("gnss");
  std::cout << result.counters.gnss_scaled << " fixes scaled, vertically by up to "
            << gnss.at("largest_noise_scale_vertical") << ", at the end "
            << gnss.at("noise_scale_vertical") << "\n";
  EXPECT_GT(result.counters.gnss_scaled, 0);
  EXPECT_EQ(gnss.at("fixes_scaled"), static_cast<double>(result.counters.gnss_scaled));
  EXPECT_GE(gnss.at("largest_noise_scale_vertical"), estimation::kMinGnssNoiseScale);
  EXPECT_THAT(
      result.warnings,
      ::testing::Contains(::testing::HasSubstr("fixes the window received took their std scaled")));
}

// Honest sigmas through the window (Eq. W9): streamed from the launch file's mount, the
// window's estimate of the effective track ended 119 mm from the batch's, its sigma 6.5 mm as
// its covariance gives it: 6.3 sigmas apart (with the batch's 17.8 mm, Eq. C8, in the sum).
// Over 31 spans of the stream its steps scatter 5.8 times as widely as predicted in the mount
// pitch and 4.0 times in the track; widened (and the pitch held at the prior, on which the
// track is conditioned), the track ends 90 mm from the batch's at a sigma of 46 mm: 1.8
// sigmas.
TEST(RealDataAcceptance, WindowSigmasCoverWhereTheBatchPutsTheTrack) {
  AUTOCAL_REQUIRE_SHARED_DATA(test::SharedDataDir("ros1_bags") / "test1.bag");
  const io::Dataset dataset = SkidSteerFromTheLaunchFileMount();
  const io::Problem problem = Shipped("skid_steer_imu_odometry_gnss.yaml");
  const io::CalibrationFile batch = CalibrateDataset(dataset, problem).calibration;
  ASSERT_TRUE(batch.uncertainty.effective_track_m.sigma.has_value());
  for (const int stretches : {32, 0}) {
    OnlineEstimationOptions options;
    options.scatter_stretches = stretches;
    const OnlineEstimationResult online = EstimateDatasetOnline(dataset, problem, options);
    const io::CalibrationFile& window = online.calibration;
    ASSERT_TRUE(window.uncertainty.effective_track_m.sigma.has_value());
    const double sigma_m = *window.uncertainty.effective_track_m.sigma;
    const double apart = std::abs(window.value.effective_track_m - batch.value.effective_track_m) /
                         std::hypot(sigma_m, *batch.uncertainty.effective_track_m.sigma);
    std::cout << "stretches " << stretches << ": track " << window.value.effective_track_m
              << " m, sigma " << sigma_m << " m, against the batch's "
              << batch.value.effective_track_m << " m: " << apart << " sigma\n";
    if (stretches > 0) {
      EXPECT_LT(apart, 3.0);
      EXPECT_THAT(online.warnings,
                  ::testing::Contains(::testing::StartsWith(
                      "the window's estimate of the mount pitch (about the vehicle's left "
                      "axis) moved over")));
    } else {
      EXPECT_GT(apart, 4.0);  // the test sees what Eq. W9 mends
    }
  }
}

// The Jackal's odometry turns about five times faster than its gyro (yaw rate scale 0.18,
// 0.20 rad/s left against 0.02 rad/s stated): slip, or a controller that reports something
// else. Without a position reference the keyframes are dead reckoned; the run says both and
// reports nothing as observable that this log cannot give.
TEST(RealDataAcceptance, RobotWithoutGpsRunsAndReportsWhatItCannotObserve) {
  const std::filesystem::path bag = test::SharedDataDir("ros1_bags") / "test2.bag";
  AUTOCAL_REQUIRE_SHARED_DATA(bag);
  const io::Dataset dataset = Import(bag);
  const auto start = std::chrono::steady_clock::now();
  const OfflineCalibrationResult result =
      CalibrateDataset(dataset, Shipped("skid_steer_imu_odometry.yaml"));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (const std::string& w : result.warnings) std::cout << "warning: " << w << "\n";
  EXPECT_LT(seconds, 30.0);
  EXPECT_THAT(result.warnings, ::testing::Contains(::testing::HasSubstr("no position reference")));
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::HasSubstr("every wheel row's sigma is scaled")));
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  EXPECT_EQ(u.odometry_speed_scale.observable, std::optional<bool>(false));
  EXPECT_EQ(u.effective_track_m.observable, std::optional<bool>(false));
  ASSERT_EQ(u.T_I_V.observable.size(), 6u);
  for (size_t i = 0; i < 6; ++i) EXPECT_FALSE(u.T_I_V.observable[i]) << i;
  EXPECT_GT(result.trajectory.size(), 100u);
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
