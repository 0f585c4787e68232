#include "autocal/pipeline/report_html.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <iomanip>
#include <limits>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "autocal/common/units.h"
#include "autocal/geometry/roll_pitch_yaw.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/calibration_block_fields.h"

namespace autocal {
namespace pipeline {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

std::vector<double> Normal(int count, double sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, sigma);
  std::vector<double> values;
  for (int i = 0; i < count; ++i) values.push_back(normal(rng));
  return values;
}

// Three outer iterations in which every block moves: the last one is the first turned and
// shifted by the amounts in the comments (none of them 1 or 3, the x axis' end labels).
std::vector<sensors::Calibration> History() {
  sensors::Calibration first;
  // Starts turned about other axes than the steps below: a chart in the wrong perturbation
  // (Log(q_k q_1^-1)) would show them about the turned axes, with the other sign.
  first.q_I_L = geometry::Exp(Eigen::Vector3d(90.0 * kDegToRad, 0.0, 0.0));
  first.q_I_V = geometry::Exp(Eigen::Vector3d(0.0, 0.0, -90.0 * kDegToRad));
  first.p_I_L = Eigen::Vector3d(0.1, 0.0, 0.5);
  first.time_offset_lidar_imu_s = 0.010;
  first.p_I_A = Eigen::Vector3d(0.0, 0.0, 1.2);
  first.p_I_V = Eigen::Vector3d(-1.0, 0.0, -0.3);
  std::vector<sensors::Calibration> history(3, first);
  for (int i = 1; i < 3; ++i) {
    sensors::Calibration& c = history[static_cast<size_t>(i)];
    const double step = i / 2.0;  // half the way, then all of it
    // 1.5 deg about z, 3.5 cm along x, ...
    c.q_I_L = first.q_I_L * geometry::Exp(Eigen::Vector3d(0.0, 0.0, step * 1.5 * kDegToRad));
    c.p_I_L.x() += step * 0.035;
    c.time_offset_lidar_imu_s += step * 0.0025;  // 2.5 ms
    c.wheel_radius_left_m += step * 0.0045;      // 4.5 mm
    c.wheel_radius_right_m -= step * 0.0025;     // -2.5 mm
    c.track_width_m += step * 0.012;             // 12 mm
    c.q_I_V = first.q_I_V * geometry::Exp(Eigen::Vector3d(step * 2.0 * kDegToRad, 0.0, 0.0));
    c.p_I_V.y() += step * 0.05;                  // 5 cm
    c.p_I_A.z() -= step * 0.08;                  // -8 cm
    c.time_offset_wheel_imu_s += step * 0.0355;  // 35.5 ms
    c.time_offset_gnss_imu_s -= step * 0.0125;   // -12.5 ms
  }
  return history;
}

// A run with the LiDAR, the IMU, the wheels and GNSS, every block estimated.
OfflineCalibrationResult FullResult() {
  OfflineCalibrationResult result;
  result.batch.calibration_per_iteration = History();
  result.batch.outer_iterations = 3;
  result.calibration.value = result.batch.calibration_per_iteration.back();
  io::CalibrationUncertainty& u = result.calibration.uncertainty;
  u.T_I_L.sigma_rot_deg = Eigen::Vector3d(0.05, 0.05, 0.02);
  u.T_I_L.sigma_p_m = Eigen::Vector3d(0.005, 0.006, 0.3);
  u.T_I_L.observable = {true, true, true, true, true, false};
  u.time_offset_lidar_imu_s.sigma = 0.0003;
  u.wheel_radius_left_m.sigma = 0.0002;
  u.wheel_radius_right_m.sigma = 0.0002;
  u.track_width_m.sigma = 0.004;
  u.p_I_A_m.sigma = Eigen::Vector3d(0.01, 0.01, 0.02);
  u.T_I_V.sigma_rot_deg = Eigen::Vector3d(0.2, 0.2, 0.2);
  u.T_I_V.sigma_p_m = Eigen::Vector3d(0.03, 0.03, 0.03);
  result.batch.associated_points = 2000;
  result.batch.initial_point_residuals_m = Normal(2000, 0.08, 1);
  result.batch.final_point_residuals_m = Normal(2000, 0.02, 2);
  result.batch.termination = "CONVERGENCE";
  result.whitened_residuals["imu"] = {Normal(900, 2.0, 3), Normal(900, 1.0, 4)};
  result.whitened_residuals["wheel"] = {Normal(500, 3.0, 5), Normal(500, 1.1, 6)};
  result.whitened_residuals["gnss"] = {Normal(300, 4.0, 7), Normal(300, 0.9, 8)};
  estimation::TimeOffsetEstimate& t = result.initialization.time_offset;
  t.reliable = true;
  t.offset_s = 0.012;
  for (int i = -20; i <= 20; ++i) {
    t.candidate_offsets_s.push_back(0.001 * i);
    t.correlation.push_back(std::exp(-0.5 * std::pow((0.001 * i - 0.012) / 0.01, 2)));
  }
  for (int i = 0; i < 50; ++i) {
    io::TrajectorySample s;
    s.t_ns = int64_t{100000000} * i;
    s.T_W_I.p = Eigen::Vector3d(2.0 * i, 0.1 * i * i, 0.0);
    result.trajectory.push_back(s);
    result.gnss_positions_W.push_back(s.T_W_I.p + Eigen::Vector3d(0.05, -0.05, 0.0));
  }
  result.warnings = {"LiDAR z translation: not excited by the drive"};
  result.seconds_total = 12.5;
  return result;
}

// The IMU, wheel and GNSS run (problem imu_wheel_gnss.yaml): no point residuals, no
// time-offset curve, a single outer iteration, no LiDAR uncertainty.
OfflineCalibrationResult ResultWithoutLidar() {
  OfflineCalibrationResult result = FullResult();
  result.batch.associated_points = 0;
  result.batch.initial_point_residuals_m.clear();
  result.batch.final_point_residuals_m.clear();
  result.batch.calibration_per_iteration.resize(1);
  result.batch.outer_iterations = 1;
  result.initialization = estimation::CalibrationInitialization();
  result.calibration.uncertainty.T_I_L = io::PoseBlockInfo();
  result.calibration.uncertainty.time_offset_lidar_imu_s = io::ScalarBlockInfo();
  return result;
}

// The figure whose caption starts with `caption`, or "" when there is none.
std::string Figure(const std::string& html, const std::string& caption) {
  const size_t begin = html.find("<figcaption>" + caption);
  if (begin == std::string::npos) return "";
  return html.substr(begin, html.find("</figure>", begin) - begin);
}

int Count(const std::string& html, const std::string& what) {
  int count = 0;
  for (size_t at = html.find(what); at != std::string::npos; at = html.find(what, at + 1)) {
    ++count;
  }
  return count;
}

// "nan" or "inf" as a word of their own (as a stream prints a non-finite double).
bool HasNonFiniteText(const std::string& html) {
  const auto is_letter = [&html](size_t i) {
    return std::isalpha(static_cast<unsigned char>(html[i])) != 0;
  };
  std::string lower(html.size(), ' ');
  std::transform(html.begin(), html.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const char* word : {"nan", "inf"}) {
    for (size_t at = lower.find(word); at != std::string::npos; at = lower.find(word, at + 1)) {
      const size_t end = at + 3;
      if ((at == 0 || !is_letter(at - 1)) && (end == html.size() || !is_letter(end))) return true;
    }
  }
  return false;
}

TEST(ReportHtml, HasResidualHistogramsForEverySensorWithData) {
  const std::string html = CalibrationReportHtml(FullResult());
  for (const char* heading : {"<h2>LiDAR residuals</h2>", "<h2>IMU residuals</h2>",
                              "<h2>Wheel odometry residuals</h2>", "<h2>GNSS residuals</h2>"}) {
    EXPECT_THAT(html, HasSubstr(heading));
  }
  // Whitened histograms carry the standard-normal reference; the LiDAR's (metres) does not.
  EXPECT_EQ(Count(html, "standard normal"), 3);
  EXPECT_THAT(Figure(html, "point-to-plane distance"), HasSubstr("before: RMS "));
  EXPECT_THAT(Figure(html, "point-to-plane distance"), Not(HasSubstr("standard normal")));
  EXPECT_THAT(html, HasSubstr("<li>LiDAR: 2000 point residuals in the last iteration</li>"));
  EXPECT_THAT(html, HasSubstr("<li>IMU: 900 whitened residual rows</li>"));
}

TEST(ReportHtml, LeavesOutSensorsWithoutResiduals) {
  OfflineCalibrationResult result = FullResult();
  result.whitened_residuals.erase("gnss");
  result.whitened_residuals["wheel"] = SensorResiduals();  // took part, nothing recorded
  const double nan = std::numeric_limits<double>::quiet_NaN();
  result.whitened_residuals["odometer"] = {{nan}, {nan, nan}};  // nothing finite to draw
  const std::string html = CalibrationReportHtml(result);
  EXPECT_THAT(html, HasSubstr("<h2>IMU residuals</h2>"));
  EXPECT_THAT(html, Not(HasSubstr("GNSS residuals")));
  EXPECT_THAT(html, Not(HasSubstr("Wheel odometry residuals")));
  EXPECT_THAT(html, Not(HasSubstr("Wheel odometry:")));
  EXPECT_THAT(html, Not(HasSubstr("odometer residuals")));
  EXPECT_EQ(Count(html, "standard normal"), 1);
}

// RMS and the share beyond +-5 sigma over the values given (Eq. R1): sqrt((4 * 1 + 49) / 5)
// and 1 of 5; a non-finite row is left out of both.
TEST(ReportHtml, StatesRmsAndShareBeyondTheRange) {
  OfflineCalibrationResult result = FullResult();
  result.whitened_residuals["gnss"] = {
      {0.5, -0.5}, {1.0, -1.0, 1.0, -1.0, 7.0, std::numeric_limits<double>::quiet_NaN()}};
  const std::string figure = Figure(CalibrationReportHtml(result), "GNSS whitened residuals");
  ASSERT_FALSE(figure.empty());
  std::ostringstream rms;
  rms << std::setprecision(4) << std::sqrt(53.0 / 5.0);
  EXPECT_THAT(figure, HasSubstr("after: RMS " + rms.str() + " σ, 20 % beyond ±5 σ (n = 5)"));
  EXPECT_THAT(figure, HasSubstr("before: RMS 0.5 σ, 0 % beyond ±5 σ (n = 2)"));
}

// One chart per estimated block; its y range is the change from the first iteration in the
// block's display unit (the last iteration's change is the largest in magnitude).
// The run summary says when the batch ended at solver.outer_iterations before converging.
TEST(ReportHtml, SaysWhenTheOuterLoopStoppedBeforeConverging) {
  OfflineCalibrationResult result = FullResult();
  result.batch.converged = true;
  EXPECT_THAT(CalibrationReportHtml(result), Not(HasSubstr("stopped before converging")));
  result.batch.converged = false;
  EXPECT_THAT(CalibrationReportHtml(result),
              HasSubstr("3 outer iterations (stopped before converging)"));
}

TEST(ReportHtml, ChartsTheConvergenceOfEveryEstimatedBlockInPhysicalUnits) {
  const std::string html = CalibrationReportHtml(FullResult());
  const struct {
    const char* caption;
    const char* extreme;  // the axis label at the far end of the change
  } blocks[] = {
      {"T_I_L rotation (deg)", ">1.5</text>"},
      {"T_I_L translation (cm)", ">3.5</text>"},
      {"LiDAR-IMU time offset (ms)", ">2.5</text>"},
      {"left rear wheel radius (mm)", ">4.5</text>"},
      {"right rear wheel radius (mm)", ">-2.5</text>"},
      {"track width (mm)", ">12</text>"},
      {"T_I_V rotation (deg)", ">2</text>"},
      {"T_I_V translation (cm)", ">5</text>"},
      {"GNSS lever arm (cm)", ">-8</text>"},
      {"wheel-IMU time offset (ms)", ">35.5</text>"},
      {"GNSS-IMU time offset (ms)", ">-12.5</text>"},
  };
  for (const auto& block : blocks) {
    const std::string figure = Figure(html, block.caption);
    ASSERT_FALSE(figure.empty()) << block.caption;
    EXPECT_THAT(figure, HasSubstr(block.extreme)) << block.caption;
  }
  // About the blocks' own axes (Eq. R3): the turned axes would read -1.5 and -2.
  EXPECT_THAT(Figure(html, "T_I_L rotation (deg)"), Not(HasSubstr(">-1.5</text>")));
  EXPECT_THAT(Figure(html, "T_I_V rotation (deg)"), Not(HasSubstr(">-2</text>")));
}

// Estimated means: moved over the iterations, or its sigma is in the result.
TEST(ReportHtml, SkipsConvergenceOfBlocksThatWereNotEstimated) {
  OfflineCalibrationResult result = FullResult();
  for (sensors::Calibration& c : result.batch.calibration_per_iteration) {
    c.q_I_V = result.batch.calibration_per_iteration.front().q_I_V;
    c.p_I_A = result.batch.calibration_per_iteration.front().p_I_A;
  }
  result.calibration.uncertainty.T_I_V = io::PoseBlockInfo();            // held, no sigma: no chart
  result.calibration.uncertainty.track_width_m = io::ScalarBlockInfo();  // moved: a chart
  const std::string html = CalibrationReportHtml(result);
  EXPECT_THAT(html, Not(HasSubstr("<figcaption>T_I_V rotation")));
  EXPECT_THAT(html, HasSubstr("<figcaption>GNSS lever arm (cm)"));  // sigma, flat
  EXPECT_THAT(html, HasSubstr("<figcaption>track width (mm)"));
  EXPECT_THAT(html, Not(HasSubstr("<td>track width (mm)</td>")));  // not in the table
}

TEST(ReportHtml, SaysSoInsteadOfChartingASingleIteration) {
  OfflineCalibrationResult result = FullResult();
  result.batch.calibration_per_iteration.resize(1);
  const std::string html = CalibrationReportHtml(result);
  EXPECT_THAT(html, HasSubstr("Only one outer iteration was recorded: no convergence chart."));
  EXPECT_THAT(html, Not(HasSubstr("outer iteration</text>")));
}

// The result table's rows for the IMU mount, from its first angle row to its translation.
std::string MountRows(const std::string& html) {
  const size_t begin = html.find("<tr><td>IMU mount roll");
  if (begin == std::string::npos) return "";
  return html.substr(begin, html.find("T_I_V translation", begin) - begin);
}

// R_V_I a half turn -+ 0.001 deg about an axis 1.3 deg from the vehicle's up axis: the IMU
// mounted upside down, the rotation a rotation vector cannot show steadily.
Eigen::Quaterniond MountNearAHalfTurn(double past_half_turn_deg) {
  const Eigen::Quaterniond R_V_I(Eigen::AngleAxisd((180.0 + past_half_turn_deg) * kDegToRad,
                                                   Eigen::Vector3d(0.01, 0.02, 1.0).normalized()));
  return R_V_I.conjugate();  // q_I_V
}

TEST(ReportHtml, PrintsAMountNearAHalfTurnAlikeOnEitherSide) {
  const Eigen::Quaterniond before = MountNearAHalfTurn(-0.001);
  const Eigen::Quaterniond after = MountNearAHalfTurn(0.001);
  // 0.002 deg apart, yet their rotation vectors point opposite ways (what the table printed).
  ASSERT_LT(geometry::AngularDistance(before, after), 0.003 * kDegToRad);
  ASSERT_GT((geometry::Log(before) - geometry::Log(after)).norm(), 6.0);
  OfflineCalibrationResult a = ResultWithoutLidar();
  a.calibration.value.q_I_V = before;
  OfflineCalibrationResult b = ResultWithoutLidar();
  b.calibration.value.q_I_V = after;
  const std::string rows = MountRows(CalibrationReportHtml(a));
  EXPECT_EQ(rows, MountRows(CalibrationReportHtml(b)));
  // Golden: estimate, sigma (about the vehicle's axes), nominal (identity), observable.
  EXPECT_EQ(rows,
            "<tr><td>IMU mount roll (about the vehicle's forward axis) (deg)</td><td>2.29</td>"
            "<td>0.2</td><td>0.00</td><td>yes</td></tr>"
            "<tr><td>IMU mount pitch (about the vehicle's left axis) (deg)</td><td>-1.15</td>"
            "<td>0.2</td><td>0.00</td><td>yes</td></tr>"
            "<tr><td>IMU mount yaw (about the vehicle's up axis) (deg)</td><td>179.98</td>"
            "<td>0.2</td><td>0.00</td><td>yes</td></tr><tr><td>");
  EXPECT_THAT(CalibrationReportHtml(a), Not(HasSubstr("rotation vector")));
}

TEST(ReportHtml, PrintsAYawOnEitherSideOfTheHalfTurnAsPlus180) {
  std::string printed[2];
  for (int side = 0; side < 2; ++side) {
    OfflineCalibrationResult result = ResultWithoutLidar();
    const double yaw_deg = side == 0 ? 179.999 : -179.999;
    result.calibration.value.q_I_V =
        geometry::FromRollPitchYaw(0.0, -0.001 * kDegToRad, yaw_deg * kDegToRad).conjugate();
    printed[side] = MountRows(CalibrationReportHtml(result));
  }
  EXPECT_EQ(printed[0], printed[1]);
  EXPECT_THAT(printed[0], HasSubstr("up axis) (deg)</td><td>180.00</td>"));
  EXPECT_THAT(printed[0], HasSubstr("left axis) (deg)</td><td>0.00</td>"));  // not -0.00
}

TEST(ReportHtml, RendersARunWithoutLidar) {
  const std::string html = CalibrationReportHtml(ResultWithoutLidar());
  EXPECT_THAT(html, HasSubstr("<li>LiDAR: not used</li>"));
  EXPECT_THAT(html, Not(HasSubstr("LiDAR residuals")));
  EXPECT_THAT(html, Not(HasSubstr("point residuals")));
  EXPECT_THAT(html, Not(HasSubstr("point-to-plane")));
  EXPECT_THAT(html, Not(HasSubstr("T_I_L roll")));
  EXPECT_THAT(html, Not(HasSubstr("LiDAR-IMU time offset")));
  EXPECT_THAT(html, Not(HasSubstr("Clock offset initialization")));
  for (const char* heading :
       {"<h2>IMU residuals</h2>", "<h2>Wheel odometry residuals</h2>", "<h2>GNSS residuals</h2>",
        "<td>track width (mm)</td>", "IMU trajectory against GNSS"}) {
    EXPECT_THAT(html, HasSubstr(heading));
  }
  EXPECT_THAT(html, HasSubstr("Only one outer iteration was recorded"));
  EXPECT_THAT(html, Not(HasSubstr("points=''")));  // no empty chart
  // Three histograms, the rig from above and from the side, the trajectory.
  EXPECT_EQ(Count(html, "<figure>"), 6);
  EXPECT_FALSE(HasNonFiniteText(html));
}

// The row of the result table whose label starts with `label`, or "" when there is none.
std::string ResultRow(const std::string& html, const std::string& label) {
  const size_t begin = html.find("<tr><td>" + label);
  if (begin == std::string::npos) return "";
  return html.substr(begin, html.find("</tr>", begin) - begin);
}

// A LiDAR block the problem fixes (here the rotation and the time offset) is shown, as the
// LiDAR took part, with sigma "–" and "fixed": it was not estimated, so not observable. The
// estimated half beside it keeps its own flags.
TEST(ReportHtml, ShowsAFixedLidarBlockAsFixedNotObservable) {
  OfflineCalibrationResult result = FullResult();
  io::CalibrationUncertainty& u = result.calibration.uncertainty;
  u.T_I_L = io::PoseBlockInfo();
  u.time_offset_lidar_imu_s = io::ScalarBlockInfo();
  const std::vector<bool> flags = {true, true, false};
  io::SetBlockUncertainty(sensors::CalibrationBlockId::kLidarTranslation,
                          Eigen::Vector3d(0.005, 0.006, 0.3), &flags, &u);
  const std::string html = CalibrationReportHtml(result);
  for (const char* label : {"T_I_L roll", "T_I_L pitch", "T_I_L yaw", "LiDAR-IMU time offset"}) {
    const std::string row = ResultRow(html, label);
    ASSERT_FALSE(row.empty()) << label;
    EXPECT_THAT(row, HasSubstr("<td>–</td>")) << row;
    EXPECT_THAT(row, HasSubstr("<td>fixed</td>")) << row;
    EXPECT_THAT(row, Not(HasSubstr("<td>yes</td>"))) << row;
  }
  EXPECT_THAT(ResultRow(html, "T_I_L translation x"), HasSubstr("<td>yes</td>"));
  EXPECT_THAT(ResultRow(html, "T_I_L translation z"), HasSubstr("<td><b>no</b></td>"));
}

// The wheels' and the receiver's clocks get result rows when estimated, and none otherwise.
TEST(ReportHtml, ShowsTheEstimatedClocksInTheResultTable) {
  OfflineCalibrationResult result = FullResult();
  EXPECT_THAT(CalibrationReportHtml(result), Not(HasSubstr("<td>wheel-IMU time offset")));
  result.calibration.value.time_offset_wheel_imu_s = -0.39;
  result.calibration.uncertainty.time_offset_wheel_imu_s.sigma = 0.002;
  result.calibration.value.time_offset_gnss_imu_s = 0.15;
  result.calibration.uncertainty.time_offset_gnss_imu_s.sigma = 0.01;
  result.calibration.uncertainty.time_offset_gnss_imu_s.observable = false;
  const std::string html = CalibrationReportHtml(result);
  EXPECT_THAT(html, HasSubstr("<td>wheel-IMU time offset (ms)</td><td>-390</td><td>2</td>"));
  EXPECT_THAT(html, HasSubstr("<td>GNSS-IMU time offset (ms)</td><td>150</td><td>10</td><td>0"
                              "</td><td><b>no</b></td>"));
}

// Wheels as odometry twist or wheel speeds: the form's blocks get their rows and charts, the
// radii and the track width (not estimated) none.
TEST(ReportHtml, ShowsTheBlocksOfTheWheelForm) {
  const auto has = [](const std::string& html, const std::string& what) {
    return html.find(what) != std::string::npos;
  };
  for (OfflineCalibrationResult result : {ResultWithoutLidar(), FullResult()}) {
    io::CalibrationUncertainty& u = result.calibration.uncertainty;
    u.wheel_radius_left_m = u.wheel_radius_right_m = u.track_width_m = io::ScalarBlockInfo();
    u.odometry_speed_scale.sigma = 0.002;
    u.effective_track_m.sigma = 0.01;
    u.effective_track_m.observable = false;
    result.calibration.value.odometry_speed_scale = 0.97;
    result.calibration.value.effective_track_m = 1.04;
    const std::string html = CalibrationReportHtml(result);
    EXPECT_TRUE(has(html, "<td>odometry speed scale (%)</td><td>97</td><td>0.2</td>"));
    EXPECT_TRUE(has(html, "<td>effective track (mm)</td><td>1040</td><td>10</td>"));
    EXPECT_FALSE(has(html, "<td>track width (mm)</td>"));
    EXPECT_FALSE(has(html, "left rear wheel speed scale"));
    EXPECT_FALSE(HasNonFiniteText(html));
    u.wheel_speed_scale_left.sigma = u.wheel_speed_scale_right.sigma = 0.001;
    EXPECT_TRUE(has(CalibrationReportHtml(result), "<td>right rear wheel speed scale (%)</td>"));
  }
  // With the iterations recorded, their convergence is charted.
  OfflineCalibrationResult result = FullResult();
  result.calibration.uncertainty.odometry_speed_scale.sigma = 0.002;
  result.calibration.uncertainty.effective_track_m.sigma = 0.01;
  const std::string html = CalibrationReportHtml(result);
  EXPECT_TRUE(has(html, "<figcaption>odometry speed scale (%)"));
  EXPECT_TRUE(has(html, "<figcaption>effective track (mm)"));
  EXPECT_FALSE(has(html, "<figcaption>left rear wheel speed scale"));
}

// The rig from above and from the side: every sensor with its ellipse, magnified by the
// stated power of ten. The LiDAR's 30 cm z sigma (FullResult) needs none; the millimetre
// ones alone would.
TEST(ReportHtml, DrawsTheRigWithSigmaEllipses) {
  const std::string html = CalibrationReportHtml(FullResult());
  const std::string top = Figure(html, "from above, vehicle frame");
  const std::string side = Figure(html, "from the side, vehicle frame");
  ASSERT_FALSE(top.empty());
  ASSERT_FALSE(side.empty());
  for (const char* sensor :
       {">IMU<", ">LiDAR<", ">GNSS antenna<", ">left rear wheel<", ">rear axle centre<"}) {
    EXPECT_THAT(top, HasSubstr(sensor)) << sensor;
  }
  EXPECT_EQ(Count(top, "<ellipse"), 6);
  EXPECT_THAT(top, HasSubstr("(1σ ellipses)"));
  OfflineCalibrationResult small = FullResult();
  small.calibration.uncertainty.T_I_L.sigma_p_m = Eigen::Vector3d(0.002, 0.002, 0.003);
  small.calibration.uncertainty.T_I_V.sigma_p_m = Eigen::Vector3d(0.003, 0.003, 0.003);
  small.calibration.uncertainty.p_I_A_m.sigma = Eigen::Vector3d(0.004, 0.004, 0.004);
  EXPECT_THAT(Figure(CalibrationReportHtml(small), "from above"), HasSubstr("(1σ ellipses ×10)"));
  // Without the mount the IMU frame stands in.
  OfflineCalibrationResult no_mount = FullResult();
  no_mount.calibration.uncertainty.T_I_V = io::PoseBlockInfo();
  EXPECT_FALSE(Figure(CalibrationReportHtml(no_mount), "from above, IMU frame").empty());
}

// A dot's centre on the page: the circle drawn just before its label.
Eigen::Vector2d DotOf(const std::string& svg, const std::string& label) {
  const std::regex dot("cx='([-0-9.]+)' cy='([-0-9.]+)'/><text[^>]*>" + label + "</text>");
  std::smatch m;
  if (!std::regex_search(svg, m, dot)) return Eigen::Vector2d::Constant(std::nan(""));
  return Eigen::Vector2d(std::stod(m[1]), std::stod(m[2]));
}

// The rig from above in the vehicle frame, with the IMU mounted turned 90 deg (FullResult's
// q_I_V, History): each sensor at p_V = R_I_V^T (p_I - p_I_V), so the IMU sits a metre to the
// left of the rear axle and the LiDAR, 13.5 cm along the IMU's x, 15 cm to the IMU's left again
// (the mount's 2 deg roll tilts the LiDAR's 0.5 m height too). The page's y axis points down;
// x and y share one scale.
TEST(ReportHtml, PlacesTheRigThroughTheMount) {
  const OfflineCalibrationResult result = FullResult();
  const sensors::Calibration& c = result.calibration.value;
  const Eigen::Matrix3d R_V_I = c.q_I_V.toRotationMatrix().transpose();
  const Eigen::Vector3d imu = R_V_I * -c.p_I_V, lidar = R_V_I * (c.p_I_L - c.p_I_V);
  ASSERT_NEAR(imu.y(), 1.0, 0.01);
  ASSERT_NEAR(lidar.y() - imu.y(), 0.152, 0.001);
  const std::string top = Figure(CalibrationReportHtml(result), "from above, vehicle frame");
  const Eigen::Vector2d axle_px = DotOf(top, "rear axle centre");
  const Eigen::Vector2d imu_px = DotOf(top, "IMU") - axle_px;
  const Eigen::Vector2d lidar_px = DotOf(top, "LiDAR") - axle_px;
  ASSERT_TRUE(imu_px.allFinite() && lidar_px.allFinite()) << top;
  const double pixels_per_m = imu_px.norm() / imu.head<2>().norm();
  const auto on_page = [&](const Eigen::Vector3d& p) -> Eigen::Vector2d {
    return Eigen::Vector2d(p.x(), -p.y()) * pixels_per_m;
  };
  EXPECT_LT((imu_px - on_page(imu)).norm(), 1.0) << imu_px.transpose();
  EXPECT_LT((lidar_px - on_page(lidar)).norm(), 1.0) << lidar_px.transpose();
}

// Each clock that was initialized shows its correlation curve; one that was not used says why.
TEST(ReportHtml, ChartsEveryClocksCorrelation) {
  OfflineCalibrationResult result = FullResult();
  estimation::WheelImuOffset wheel;
  wheel.signal = "yaw rate";
  wheel.estimate.offset_s = -0.39;
  wheel.estimate.reliable = true;
  estimation::SeriesOffsetEstimate gnss;
  gnss.offset_s = 0.2;
  gnss.reason = "the peak lies at the edge of the range";
  for (int i = -10; i <= 10; ++i) {
    wheel.estimate.candidate_offsets_s.push_back(0.1 * i);
    wheel.estimate.correlation.push_back(1.0 - std::abs(0.1 * i + 0.39));
    gnss.candidate_offsets_s.push_back(0.1 * i);
    gnss.correlation.push_back(0.1 * i);
  }
  result.wheel_clock_initialization = wheel;
  result.gnss_clock_initialization = gnss;
  const std::string html = CalibrationReportHtml(result);
  EXPECT_THAT(html, HasSubstr("<h2>Clock offset initialization</h2>"));
  EXPECT_FALSE(Figure(html, "LiDAR vs gyro").empty());
  EXPECT_FALSE(Figure(html, "wheels vs IMU, yaw rate (peak -390 ms)").empty());
  EXPECT_FALSE(Figure(html, "GNSS track speed vs wheel speed (peak 200 ms, not used: the peak lies")
                   .empty());
  EXPECT_THAT(CalibrationReportHtml(ResultWithoutLidar()),
              Not(HasSubstr("Clock offset initialization")));
}

// The LiDAR curve's caption names the curve's own peak and says when that peak did not start
// the solve: the initializer found no reliable peak (the offset then holds the fallback the
// solve started from, not the curve's peak), or the problem fixes the offset.
TEST(ReportHtml, SaysWhenTheLidarClocksPeakWasNotUsed) {
  OfflineCalibrationResult result = FullResult();  // the curve peaks at 12 ms
  EXPECT_FALSE(
      Figure(CalibrationReportHtml(result), "LiDAR vs gyro angular-rate correlation (peak 12 ms)")
          .empty());
  EXPECT_THAT(CalibrationReportHtml(result), Not(HasSubstr("not used")));
  estimation::TimeOffsetEstimate& t = result.initialization.time_offset;
  t.reliable = false;
  t.reason = "no turns";
  t.offset_s = 0.05;  // the fallback
  std::string html = CalibrationReportHtml(result);
  EXPECT_FALSE(
      Figure(html, "LiDAR vs gyro angular-rate correlation (peak 12 ms, not used: no turns)")
          .empty())
      << html.substr(html.find("LiDAR vs gyro"), 120);
  EXPECT_THAT(html, Not(HasSubstr("peak 50 ms")));
  t.reliable = true;
  t.offset_s = 0.012;
  result.calibration.uncertainty.time_offset_lidar_imu_s = io::ScalarBlockInfo();
  html = CalibrationReportHtml(result);
  EXPECT_FALSE(Figure(html,
                      "LiDAR vs gyro angular-rate correlation (peak 12 ms, not used: the problem "
                      "fixes the LiDAR-IMU time offset)")
                   .empty());
  // Estimated, but from the nominal value: the odometry did not follow the drive.
  result = FullResult();
  result.lidar_blocks_from_nominal = true;
  EXPECT_FALSE(Figure(CalibrationReportHtml(result),
                      "LiDAR vs gyro angular-rate correlation (peak 12 ms, not used: the "
                      "keyframes were rebuilt from GNSS and the IMU, and the offset started from "
                      "its nominal value)")
                   .empty());
}

// Every element the page opens is closed in order (the void elements excepted), and every
// attribute value is quoted: the page parses the same in any browser.
TEST(ReportHtml, IsWellFormed) {
  for (const OfflineCalibrationResult& result : {FullResult(), ResultWithoutLidar()}) {
    const std::string html = CalibrationReportHtml(result);
    std::vector<std::string> open;
    const std::regex tag(R"(<(/?)([a-zA-Z][a-zA-Z0-9]*)([^>]*)>)");
    for (auto it = std::sregex_iterator(html.begin(), html.end(), tag);
         it != std::sregex_iterator(); ++it) {
      const std::string name = (*it)[2].str();
      const std::string attributes = (*it)[3].str();
      if ((*it)[1].str().empty()) {
        EXPECT_FALSE(std::regex_search(attributes, std::regex(R"(=[^'"])"))) << (*it)[0];
        const bool self_closed = !attributes.empty() && attributes.back() == '/';
        const bool void_element = name == "meta" || name == "br";
        if (!self_closed && !void_element) open.push_back(name);
      } else {
        ASSERT_FALSE(open.empty()) << "</" << name << "> closes nothing";
        ASSERT_EQ(open.back(), name) << "</" << name << "> closes <" << open.back() << ">";
        open.pop_back();
      }
    }
    EXPECT_TRUE(open.empty()) << open.size() << " elements left open, first <" << open.front()
                              << ">";
  }
}

// The sensors' lines say how many factors the robust loss down-weighted.
TEST(ReportHtml, SaysHowManyFactorsTheLossDownWeighted) {
  OfflineCalibrationResult result = FullResult();
  result.whitened_residuals["gnss"].factors = 100;
  result.whitened_residuals["gnss"].factors_downweighted = 4;
  result.whitened_residuals["gnss"].rms_not_downweighted = 0.97;
  const std::string html = CalibrationReportHtml(result);
  EXPECT_THAT(html, HasSubstr("GNSS: 300 whitened residual rows; the robust loss down-weighted 4 "
                              "of 100 factors (the others' RMS 0.97)"));
  EXPECT_THAT(html, Not(HasSubstr("IMU: 900 whitened residual rows; the robust loss")));
}

TEST(ReportHtml, IsSelfContained) {
  for (const OfflineCalibrationResult& result : {FullResult(), ResultWithoutLidar()}) {
    const std::string html = CalibrationReportHtml(result);
    EXPECT_THAT(html, Not(HasSubstr("http://")));
    EXPECT_THAT(html, Not(HasSubstr("https://")));
    EXPECT_THAT(html, Not(HasSubstr("<script")));
    EXPECT_THAT(html, Not(HasSubstr("<link")));
    EXPECT_THAT(html, Not(HasSubstr("src=")));
    EXPECT_THAT(html, Not(HasSubstr("url(")));
    EXPECT_THAT(html, HasSubstr("</html>"));
  }
}

TEST(ReportHtml, EscapesText) {
  OfflineCalibrationResult result = FullResult();
  result.warnings = {"radius <left> & 'right' \"both\""};
  result.batch.termination = "<stop>";
  result.whitened_residuals["<odd>"] = {{1.0}, {0.5}};
  const std::string html = CalibrationReportHtml(result);
  EXPECT_THAT(html, HasSubstr("radius &lt;left&gt; &amp; &#39;right&#39; &quot;both&quot;"));
  EXPECT_THAT(html, Not(HasSubstr("<left>")));
  EXPECT_THAT(html, HasSubstr("Solver: &lt;stop&gt;"));
  EXPECT_THAT(html, HasSubstr("<h2>&lt;odd&gt; residuals</h2>"));
  EXPECT_THAT(html, Not(HasSubstr("<odd>")));
}

TEST(ReportHtml, PrintsNoNonFiniteNumbers) {
  // An empty result: every statistic over empty inputs.
  const std::string empty = CalibrationReportHtml(OfflineCalibrationResult());
  EXPECT_FALSE(HasNonFiniteText(empty)) << empty;
  EXPECT_THAT(empty, Not(HasSubstr("<figure>")));
  EXPECT_THAT(empty, HasSubstr("LiDAR: not used"));
  EXPECT_THAT(empty, HasSubstr("No outer iteration was recorded"));
  EXPECT_THAT(empty, Not(HasSubstr("Trajectory")));
  // Non-finite inputs everywhere a number is printed or drawn.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  OfflineCalibrationResult result = FullResult();
  result.batch.final_point_residuals_m.push_back(nan);
  result.whitened_residuals["imu"].after = {inf, -inf, nan};
  result.initialization.time_offset.correlation[3] = nan;
  result.initialization.time_offset.offset_s = nan;
  result.calibration.value.track_width_m = inf;
  result.calibration.uncertainty.track_width_m.sigma = nan;
  result.batch.calibration_per_iteration[1].wheel_radius_left_m = nan;
  result.gnss_positions_W.push_back(Eigen::Vector3d::Constant(nan));
  result.seconds_total = nan;
  const std::string html = CalibrationReportHtml(result);
  EXPECT_FALSE(HasNonFiniteText(html));
  // The IMU kept its "before" histogram; its non-finite "after" rows are not counted.
  EXPECT_THAT(Figure(html, "IMU whitened residuals"), HasSubstr("before: RMS"));
  EXPECT_THAT(Figure(html, "IMU whitened residuals"), Not(HasSubstr("after: RMS")));
}

// The checker above must see what a stream prints for non-finite values.
TEST(ReportHtml, NonFiniteCheckerFindsStreamedValues) {
  EXPECT_TRUE(HasNonFiniteText("<td>nan</td>"));
  EXPECT_TRUE(HasNonFiniteText("x='-inf'"));
  EXPECT_TRUE(HasNonFiniteText("RMS NaN m"));
  EXPECT_FALSE(HasNonFiniteText("initialization, information, finance"));
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
