#include "autocal/evaluation/evaluation.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/csv_files.h"
#include "autocal/io/tum_trajectory.h"
#include "autocal/sim/simulator.h"
#include "support/test_paths.h"

namespace autocal {
namespace evaluation {
namespace {

using ::testing::HasSubstr;

constexpr int64_t kStartNs = 1'700'000'000'000'000'000;
constexpr int64_t kStepNs = 10'000'000;  // truth at 100 Hz

Eigen::Quaterniond YawQuaternion(double yaw_rad) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()));
}

// A drive along a circle of radius 20 m at 5 m/s with slow vertical motion, roll and pitch:
// every pose has a closed form, so interpolation and alignment errors can be bounded.
io::TrajectorySample TrueStateAt(int64_t t_ns) {
  const double t = SecondsBetween(kStartNs, t_ns);
  const double yaw = 0.25 * t;
  io::TrajectorySample s;
  s.t_ns = t_ns;
  s.T_W_I.p << 20.0 * std::sin(yaw), 20.0 * (1.0 - std::cos(yaw)), 0.5 * std::sin(0.3 * t);
  s.T_W_I.q =
      YawQuaternion(yaw) *
      Eigen::Quaterniond(Eigen::AngleAxisd(0.03 * std::sin(0.7 * t), Eigen::Vector3d::UnitY())) *
      Eigen::Quaterniond(Eigen::AngleAxisd(0.05 * std::sin(1.3 * t), Eigen::Vector3d::UnitX()));
  return s;
}

io::Trajectory TrueTrajectory(double duration_s) {
  io::Trajectory truth;
  for (int64_t t_ns = kStartNs; t_ns <= kStartNs + SecondsToNs(duration_s); t_ns += kStepNs)
    truth.push_back(TrueStateAt(t_ns));
  return truth;
}

// The trajectory expressed in another gravity-aligned world frame W': T_W'_I = T_W'_W T_W_I
// with T_W'_W = (Rz(yaw), t).
io::Trajectory InOtherWorld(const io::Trajectory& trajectory, double yaw_rad,
                            const Eigen::Vector3d& t) {
  const geometry::Pose3d T_Wp_W(YawQuaternion(yaw_rad), t);
  io::Trajectory out = trajectory;
  for (io::TrajectorySample& s : out) s.T_W_I = T_Wp_W * s.T_W_I;
  return out;
}

TEST(CalibrationErrorsTest, KnownPerturbationsGiveExactlyTheirErrors) {
  const sensors::Calibration truth = sim::DefaultTrueCalibration();
  sensors::Calibration estimate = truth;
  const Eigen::Vector3d delta_L_deg(0.1, -0.2, 0.3);
  estimate.q_I_L = truth.q_I_L * geometry::Exp(Eigen::Vector3d(kDegToRad * delta_L_deg));
  estimate.p_I_L += Eigen::Vector3d(0.001, -0.002, 0.003);
  estimate.time_offset_lidar_imu_s += 0.0015;
  estimate.wheel_radius_left_m *= 1.01;
  estimate.wheel_radius_right_m *= 0.995;
  estimate.track_width_m += 0.0162;
  estimate.p_I_A += Eigen::Vector3d(0.005, 0.0, -0.012);
  const Eigen::Vector3d delta_V_deg(-0.5, 0.0, 2.0);
  estimate.q_I_V = truth.q_I_V * geometry::Exp(Eigen::Vector3d(kDegToRad * delta_V_deg));
  estimate.p_I_V += Eigen::Vector3d(0.0, 0.02, 0.0);
  estimate.wheel_speed_scale_left += 0.012;
  estimate.odometry_speed_scale -= 0.03;
  estimate.effective_track_m += 0.08;

  const CalibrationErrors e = CompareCalibration(estimate, truth);
  constexpr double kTol = 1e-9;
  EXPECT_TRUE(e.T_I_L.rotation_deg.isApprox(delta_L_deg, kTol)) << e.T_I_L.rotation_deg.transpose();
  EXPECT_NEAR(e.T_I_L.RotationAngleDeg(), delta_L_deg.norm(), kTol);
  EXPECT_TRUE(e.T_I_L.translation_mm.isApprox(Eigen::Vector3d(1, -2, 3), kTol))
      << e.T_I_L.translation_mm.transpose();
  EXPECT_NEAR(e.T_I_L.TranslationNormMm(), std::sqrt(14.0), kTol);
  EXPECT_NEAR(e.time_offset_ms, 1.5, kTol);
  EXPECT_NEAR(e.wheel_radius_left_percent, 1.0, kTol);
  EXPECT_NEAR(e.wheel_radius_right_percent, -0.5, kTol);
  EXPECT_NEAR(e.track_width_percent, 100.0 * 0.0162 / truth.track_width_m, kTol);
  EXPECT_NEAR(e.wheel_speed_scale_left_percent, 100.0 * 0.012 / truth.wheel_speed_scale_left, kTol);
  EXPECT_NEAR(e.wheel_speed_scale_right_percent, 0.0, kTol);
  EXPECT_NEAR(e.odometry_speed_scale_percent, -100.0 * 0.03 / truth.odometry_speed_scale, kTol);
  EXPECT_NEAR(e.effective_track_percent, 100.0 * 0.08 / truth.effective_track_m, kTol);
  EXPECT_TRUE(e.p_I_A_mm.isApprox(Eigen::Vector3d(5, 0, -12), kTol)) << e.p_I_A_mm.transpose();
  EXPECT_NEAR(e.p_I_A_mm.norm(), 13.0, kTol);
  EXPECT_TRUE(e.T_I_V.rotation_deg.isApprox(delta_V_deg, kTol)) << e.T_I_V.rotation_deg.transpose();
  EXPECT_NEAR(e.T_I_V.TranslationNormMm(), 20.0, kTol);

  const CalibrationErrors zero = CompareCalibration(truth, truth);
  EXPECT_EQ(zero.T_I_L.RotationAngleDeg(), 0.0);
  EXPECT_EQ(zero.time_offset_ms, 0.0);
  EXPECT_EQ(zero.wheel_radius_left_percent, 0.0);
}

TEST(CalibrationErrorsTest, TheSignOfTheQuaternionDoesNotMatter) {
  const sensors::Calibration truth = sim::DefaultTrueCalibration();
  sensors::Calibration estimate = truth;
  estimate.q_I_L.coeffs() = -truth.q_I_L.coeffs();
  EXPECT_NEAR(CompareCalibration(estimate, truth).T_I_L.RotationAngleDeg(), 0.0, 1e-9);
}

TEST(CalibrationErrorsTest, ANonPositiveTrueRadiusIsAnError) {
  sensors::Calibration truth;
  truth.wheel_radius_left_m = 0.0;
  EXPECT_THROW(CompareCalibration(sensors::Calibration(), truth), Error);
}

TEST(TrajectoryErrorsTest, AYawRotatedAndShiftedCopyHasZeroAte) {
  const io::Trajectory truth = TrueTrajectory(60.0);
  const double yaw = 37.0 * kDegToRad;
  const Eigen::Vector3d shift(12.0, -5.0, 3.0);
  const TrajectoryErrors e = CompareTrajectory(InOtherWorld(truth, yaw, shift), truth);
  EXPECT_EQ(e.matched_poses, static_cast<int>(truth.size()));
  EXPECT_EQ(e.exact_matches, e.matched_poses);
  EXPECT_EQ(e.unmatched_poses, 0);
  EXPECT_LT(e.ate_translation_rmse_m, 1e-9);
  EXPECT_LT(e.ate_rotation_rmse_deg, 1e-6);
  EXPECT_LT(e.max_translation_error_m, 1e-9);
  // The alignment is the inverse of T_W'_W: yaw -37 deg, t = -Rz(-yaw) shift.
  EXPECT_NEAR(e.alignment.yaw_rad, -yaw, 1e-12);
  EXPECT_TRUE(e.alignment.translation_m.isApprox(-(YawQuaternion(-yaw) * shift), 1e-9))
      << e.alignment.translation_m.transpose();
  EXPECT_FALSE(e.alignment.yaw_from_orientation);
}

TEST(TrajectoryErrorsTest, PositionNoiseOfKnownRmsGivesThatRms) {
  const io::Trajectory truth = TrueTrajectory(60.0);
  io::Trajectory estimate = InOtherWorld(truth, -2.0, Eigen::Vector3d(-100.0, 40.0, 0.5));
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.05);
  double sum_sq = 0.0;
  for (io::TrajectorySample& s : estimate) {
    const Eigen::Vector3d n(noise(rng), noise(rng), noise(rng));
    s.T_W_I.p += n;
    sum_sq += n.squaredNorm();
  }
  const double noise_rms = std::sqrt(sum_sq / static_cast<double>(estimate.size()));
  const TrajectoryErrors e = CompareTrajectory(estimate, truth);
  // The alignment absorbs 4 of the 3n noise components: a relative change of ~4/(3n).
  EXPECT_NEAR(e.ate_translation_rmse_m, noise_rms, 0.01 * noise_rms)
      << "noise RMS " << noise_rms << ", ATE " << e.ate_translation_rmse_m;
  EXPECT_LE(e.ate_translation_rmse_m, noise_rms);  // least squares never does worse than truth
}

TEST(TrajectoryErrorsTest, RotationNoiseOfKnownAngleGivesThatAngle) {
  const io::Trajectory truth = TrueTrajectory(30.0);
  io::Trajectory estimate = InOtherWorld(truth, 1.0, Eigen::Vector3d(3.0, 4.0, 5.0));
  std::mt19937 rng(11);
  std::normal_distribution<double> normal;
  const double angle_deg = 0.5;
  for (io::TrajectorySample& s : estimate) {
    const Eigen::Vector3d axis =
        Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
    s.T_W_I.q = s.T_W_I.q * geometry::Exp(Eigen::Vector3d(angle_deg * kDegToRad * axis));
  }
  const TrajectoryErrors e = CompareTrajectory(estimate, truth);
  EXPECT_NEAR(e.ate_rotation_rmse_deg, angle_deg, 1e-6);
  EXPECT_NEAR(e.max_rotation_error_deg, angle_deg, 1e-6);
  EXPECT_LT(e.ate_translation_rmse_m, 1e-9);
}

// Tilt is the roll and pitch part: a pose turned about its own up direction keeps it, one
// turned about a horizontal axis of the body by an angle tilts by that angle.
TEST(TrajectoryErrorsTest, TiltIsTheAngleBetweenTheUpDirections) {
  const io::Trajectory truth = TrueTrajectory(30.0);
  io::Trajectory estimate = InOtherWorld(truth, 1.0, Eigen::Vector3d(3.0, 4.0, 5.0));
  const double heading_deg = 0.5;
  const double tilt_deg = 0.3;
  for (size_t i = 0; i < estimate.size(); ++i) {
    Eigen::Quaterniond& q = estimate[i].T_W_I.q;
    const Eigen::Vector3d up = q.conjugate() * Eigen::Vector3d::UnitZ();  // in the body
    const Eigen::Vector3d axis = i % 2 == 0 ? up : up.cross(Eigen::Vector3d::UnitX()).normalized();
    q = q *
        geometry::Exp(Eigen::Vector3d((i % 2 == 0 ? heading_deg : tilt_deg) * kDegToRad * axis));
  }
  const TrajectoryErrors e = CompareTrajectory(estimate, truth);
  const double tilted = static_cast<double>(estimate.size() / 2);  // the odd poses
  EXPECT_NEAR(e.tilt_rmse_deg, tilt_deg * std::sqrt(tilted / estimate.size()), 1e-9);
  // Half the poses carry the heading error, which the yaw alignment shares out.
  EXPECT_GT(e.ate_rotation_rmse_deg, e.tilt_rmse_deg);
  EXPECT_LT(
      CompareTrajectory(InOtherWorld(truth, -2.0, Eigen::Vector3d::Zero()), truth).tilt_rmse_deg,
      1e-6);
}

TEST(TrajectoryErrorsTest, StampsBetweenTruthSamplesAreInterpolated) {
  const io::Trajectory truth = TrueTrajectory(20.0);
  // Estimates 3 ms after each truth stamp, from the closed form; one before the truth starts
  // and one after it ends.
  io::Trajectory estimate;
  estimate.push_back(TrueStateAt(kStartNs - 3'000'000));
  for (size_t i = 0; i + 1 < truth.size(); ++i)
    estimate.push_back(TrueStateAt(truth[i].t_ns + 3'000'000));
  estimate.push_back(TrueStateAt(truth.back().t_ns + 3'000'000));
  const TrajectoryErrors e =
      CompareTrajectory(InOtherWorld(estimate, 0.3, Eigen::Vector3d(1, 2, 3)), truth);
  EXPECT_EQ(e.matched_poses, static_cast<int>(truth.size()) - 1);
  EXPECT_EQ(e.exact_matches, 0);
  EXPECT_EQ(e.unmatched_poses, 2);
  // Linear interpolation over 10 ms at 5 m/s on a 20 m circle: sagitta (0.05 m)^2 / (8 * 20 m)
  // = 16 µm at most; slerp of a rotation whose rate changes slowly: below 1e-4 deg.
  EXPECT_LT(e.ate_translation_rmse_m, 2e-5);
  EXPECT_LT(e.ate_rotation_rmse_deg, 2e-4);
}

TEST(TrajectoryErrorsTest, PosesInATruthGapAreLeftOut) {
  io::Trajectory truth = TrueTrajectory(20.0);
  // Remove 0.5 s of truth (10.0 s to 10.5 s): wider than the 0.1 s interpolation limit.
  truth.erase(truth.begin() + 1001, truth.begin() + 1050);
  io::Trajectory estimate;
  for (int64_t t_ns = kStartNs + 5'000'000; t_ns < kStartNs + SecondsToNs(20.0);
       t_ns += 100'000'000)
    estimate.push_back(TrueStateAt(t_ns));
  const TrajectoryErrors e = CompareTrajectory(estimate, truth);
  EXPECT_EQ(e.unmatched_poses, 5);  // 10.005, 10.105, 10.205, 10.305, 10.405 s
  EXPECT_EQ(e.matched_poses, static_cast<int>(estimate.size()) - 5);
}

TEST(TrajectoryErrorsTest, AParkedCarTakesItsYawFromTheOrientations) {
  io::Trajectory truth;
  for (int i = 0; i < 100; ++i) {
    io::TrajectorySample s;
    s.t_ns = kStartNs + i * kStepNs;
    s.T_W_I.q =
        YawQuaternion(0.4) * Eigen::Quaterniond(Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitX()));
    s.T_W_I.p = Eigen::Vector3d(5.0, 6.0, 1.0);
    truth.push_back(s);
  }
  const TrajectoryErrors e =
      CompareTrajectory(InOtherWorld(truth, -1.1, Eigen::Vector3d(7, 8, 9)), truth);
  EXPECT_TRUE(e.alignment.yaw_from_orientation);
  EXPECT_NEAR(e.alignment.yaw_rad, 1.1, 1e-12);
  EXPECT_LT(e.ate_translation_rmse_m, 1e-12);
  EXPECT_LT(e.ate_rotation_rmse_deg, 1e-6);
}

TEST(TrajectoryErrorsTest, NoOverlapIsAnError) {
  const io::Trajectory truth = TrueTrajectory(5.0);
  io::Trajectory late = truth;
  for (io::TrajectorySample& s : late) s.t_ns += SecondsToNs(100.0);
  try {
    CompareTrajectory(late, truth);
    ADD_FAILURE() << "no error for trajectories that do not overlap";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("falls within the ground truth's time span"));
  }
}

// An evaluation with known errors: T_I_L 0.3 deg / 5 mm, offset -2 ms, radii +1 % / -0.2 %,
// track width 0.5 %, lever arm 13 mm, T_I_V exact.
Evaluation KnownEvaluation() {
  Evaluation evaluation;
  CalibrationErrors& c = evaluation.calibration;
  c.T_I_L.rotation_deg = Eigen::Vector3d(0.0, 0.0, 0.3);
  c.T_I_L.translation_mm = Eigen::Vector3d(3.0, 4.0, 0.0);
  c.time_offset_ms = -2.0;
  c.wheel_radius_left_percent = 1.0;
  c.wheel_radius_right_percent = -0.2;
  c.track_width_percent = 0.5;
  c.p_I_A_mm = Eigen::Vector3d(5.0, 0.0, -12.0);
  return evaluation;
}

std::vector<std::string> Names(const std::vector<ThresholdViolation>& violations) {
  std::vector<std::string> names;
  for (const ThresholdViolation& v : violations) names.push_back(v.metric + "/" + v.threshold);
  return names;
}

TEST(ThresholdsTest, ExceededLimitsAreNamed) {
  const Evaluation evaluation = KnownEvaluation();
  EXPECT_TRUE(ExceededThresholds(evaluation, Thresholds()).empty());

  Thresholds t;
  t.max_rotation_deg = 0.5;         // 0.3: ok
  t.max_translation_mm = 4.0;       // 5: exceeded
  t.max_time_offset_ms = 1.0;       // |-2|: exceeded (the sign does not matter)
  t.max_radius_percent = 0.5;       // left 1: exceeded, right 0.2: ok
  t.max_track_width_percent = 0.5;  // 0.5: on the limit is ok
  t.max_lever_arm_mm = 20.0;        // 13: ok
  const std::vector<ThresholdViolation> violations = ExceededThresholds(evaluation, t);
  EXPECT_THAT(Names(violations), ::testing::ElementsAre("T_I_L translation/max_translation_mm",
                                                        "LiDAR time offset/max_time_offset_ms",
                                                        "wheel radius left/max_radius_percent"));
  ASSERT_EQ(violations.size(), 3u);
  EXPECT_DOUBLE_EQ(violations[0].value, 5.0);
  EXPECT_DOUBLE_EQ(violations[0].limit, 4.0);
  EXPECT_DOUBLE_EQ(violations[1].value, 2.0);
  EXPECT_EQ(violations[0].ToString(), "T_I_L translation 5 mm > max_translation_mm 4");

  // An ATE limit without an evaluated trajectory never passes.
  Thresholds ate;
  ate.max_ate_m = 0.1;
  const std::vector<ThresholdViolation> unmeasured = ExceededThresholds(evaluation, ate);
  ASSERT_EQ(unmeasured.size(), 1u);
  EXPECT_TRUE(std::isnan(unmeasured[0].value));
  EXPECT_THAT(unmeasured[0].ToString(), HasSubstr("not measured"));

  Evaluation with_trajectory = evaluation;
  with_trajectory.trajectory = TrajectoryErrors();
  with_trajectory.trajectory->ate_translation_rmse_m = 0.25;
  with_trajectory.trajectory->ate_rotation_rmse_deg = 0.05;
  ate.max_ate_deg = 0.1;
  EXPECT_THAT(Names(ExceededThresholds(with_trajectory, ate)),
              ::testing::ElementsAre("ATE translation RMSE/max_ate_m"));

  Thresholds negative;
  negative.max_lever_arm_mm = -1.0;
  EXPECT_THROW(ExceededThresholds(evaluation, negative), Error);
}

TEST(ThresholdsTest, TableAndYamlReportEveryMetricAndVerdict) {
  const Evaluation evaluation = KnownEvaluation();
  Thresholds t;
  t.max_translation_mm = 4.0;
  t.max_radius_percent = 2.0;
  const std::string table = FormatEvaluationTable(evaluation, t);
  for (const char* metric :
       {"T_I_L rotation", "T_I_L translation", "LiDAR time offset", "wheel radius left",
        "wheel radius right", "track width", "speed scale left", "speed scale right",
        "odometry speed scale", "effective track", "lever arm p_I_A", "T_I_V rotation",
        "T_I_V translation", "wheel clock offset", "GNSS clock offset", "ATE translation RMSE",
        "ATE rotation RMSE"}) {
    EXPECT_THAT(table, HasSubstr(metric));
  }
  EXPECT_THAT(table, HasSubstr("EXCEEDED"));

  const std::string path = (test::OutputDir("yaml") / "evaluation.yaml").string();
  WriteEvaluationYaml(path, evaluation, t);
  const YAML::Node root = YAML::LoadFile(path);
  EXPECT_DOUBLE_EQ(root["calibration"]["T_I_L"]["translation_error_mm"].as<double>(), 5.0);
  EXPECT_DOUBLE_EQ(root["calibration"]["time_offset_error_ms"].as<double>(), -2.0);
  EXPECT_DOUBLE_EQ(root["calibration"]["p_I_A"]["error_axes_mm"][2].as<double>(), -12.0);
  EXPECT_FALSE(root["trajectory"].IsDefined());
  EXPECT_DOUBLE_EQ(root["thresholds"]["max_radius_percent"].as<double>(), 2.0);
  EXPECT_EQ(root["thresholds"].size(), 2u);
  ASSERT_EQ(root["exceeded"].size(), 1u);
  EXPECT_EQ(root["exceeded"][0]["threshold"].as<std::string>(), "max_translation_mm");
  EXPECT_EQ(root["exceeded"][0]["metric"].as<std::string>(), "T_I_L translation");
  EXPECT_FALSE(root["passed"].as<bool>());
}

// A block the result did not estimate (no sigma: held fixed, or a sensor the problem left out)
// carries the nominal value's error: the table says "not estimated" and a limit on it never
// passes. The wheels' and the receiver's clocks are compared like the LiDAR's.
TEST(ThresholdsTest, ABlockNotEstimatedIsNotMeasured) {
  Evaluation evaluation = KnownEvaluation();
  evaluation.calibration.wheel_time_offset_ms = -85.0;
  evaluation.calibration.gnss_time_offset_ms = 3.0;
  evaluation.estimated.T_I_L = false;
  Thresholds t;
  t.max_rotation_deg = 0.5;  // 0.3 deg, but not estimated
  t.max_wheel_time_offset_ms = 5.0;
  t.max_gnss_time_offset_ms = 5.0;
  const std::vector<ThresholdViolation> violations = ExceededThresholds(evaluation, t);
  EXPECT_THAT(Names(violations),
              ::testing::ElementsAre("T_I_L rotation/max_rotation_deg",
                                     "wheel clock offset/max_wheel_time_offset_ms"));
  ASSERT_EQ(violations.size(), 2u);
  EXPECT_EQ(violations[0].ToString(),
            "T_I_L rotation not estimated by the result, but max_rotation_deg is given");
  EXPECT_EQ(violations[1].ToString(), "wheel clock offset 85 ms > max_wheel_time_offset_ms 5");
  const std::string table = FormatEvaluationTable(evaluation, t);
  EXPECT_THAT(table, HasSubstr("T_I_L rotation         not estimated"));
  const YAML::Node root = YAML::Load(EvaluationYamlText(evaluation, t));
  EXPECT_DOUBLE_EQ(root["calibration"]["wheel_time_offset_error_ms"].as<double>(), -85.0);
  ASSERT_EQ(root["calibration"]["not_estimated"].size(), 1u);
  EXPECT_EQ(root["calibration"]["not_estimated"][0].as<std::string>(), "T_I_L");
}

TEST(EvaluateResultTest, ReadsTheDatasetTruthAndTheResultDirectory) {
  // Start empty: files left by an earlier run would change what is evaluated.
  const std::filesystem::path root = test::OutputDir("evaluate_result");
  std::filesystem::remove_all(root);
  const std::filesystem::path dataset = root / "dataset";
  const std::filesystem::path result = root / "result";
  std::filesystem::create_directories(dataset / "groundtruth");
  std::filesystem::create_directories(result);
  const sensors::Calibration truth = sim::DefaultTrueCalibration();
  io::CalibrationFile truth_file;
  truth_file.value = truth;
  io::WriteCalibrationYaml((dataset / "groundtruth" / "calibration.yaml").string(), truth_file);
  const ResultPaths paths = ResultPaths::For(dataset.string(), result.string());

  io::CalibrationFile estimate = truth_file;
  estimate.value.time_offset_lidar_imu_s += 0.004;
  estimate.value.p_I_A.z() += 0.01;
  io::WriteCalibrationYaml(paths.result_calibration, estimate);
  const Evaluation without_trajectory = EvaluateResult(paths);
  EXPECT_NEAR(without_trajectory.calibration.time_offset_ms, 4.0, 1e-9);
  EXPECT_NEAR(without_trajectory.calibration.p_I_A_mm.z(), 10.0, 1e-9);
  EXPECT_FALSE(without_trajectory.trajectory.has_value());
  // Without any sigma the file says nothing about what was estimated: every block counts.
  EXPECT_TRUE(without_trajectory.estimated.T_I_L);
  // With sigmas, a block without one was not estimated.
  estimate.uncertainty.time_offset_lidar_imu_s.sigma = 1e-4;
  io::WriteCalibrationYaml(paths.result_calibration, estimate);
  const EstimatedBlocks estimated = EvaluateResult(paths).estimated;
  EXPECT_TRUE(estimated.time_offset);
  EXPECT_FALSE(estimated.T_I_L);
  EXPECT_FALSE(estimated.gnss_time_offset);

  // A result trajectory needs the dataset's.
  const io::Trajectory trajectory = TrueTrajectory(10.0);
  io::WriteTumTrajectory(paths.result_trajectory,
                         InOtherWorld(trajectory, 0.7, Eigen::Vector3d(1, 1, 1)));
  try {
    EvaluateResult(paths);
    ADD_FAILURE() << "no error without groundtruth/trajectory.csv";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr(paths.truth_trajectory));
  }
  io::WriteTrajectoryCsv(paths.truth_trajectory, trajectory);
  const Evaluation with_trajectory = EvaluateResult(paths);
  ASSERT_TRUE(with_trajectory.trajectory.has_value());
  EXPECT_EQ(with_trajectory.trajectory_file, paths.result_trajectory);
  EXPECT_THAT(EvaluationYamlText(with_trajectory, Thresholds()),
              HasSubstr("  file: \"" + paths.result_trajectory + "\"\n"));
  EXPECT_EQ(with_trajectory.trajectory->matched_poses, static_cast<int>(trajectory.size()));
  // TUM stores the pose with shortest round-trip decimals: the ATE is rounding only.
  EXPECT_LT(with_trajectory.trajectory->ate_translation_rmse_m, 1e-9);

  const ResultPaths missing = ResultPaths::For(dataset.string(), (result / "nothing").string());
  try {
    EvaluateResult(missing);
    ADD_FAILURE() << "no error for a missing result";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr(missing.result_calibration));
  }
}

}  // namespace
}  // namespace evaluation
}  // namespace autocal
