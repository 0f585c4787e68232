#include "autocal/pipeline/report_html.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "autocal/common/format.h"
#include "autocal/geometry/se3.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/calibration_block_fields.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/sensors/calibration_blocks.h"
#include "html_page.h"
#include "mount_angles.h"
#include "report_bound.h"
#include "svg_chart.h"

namespace autocal {
namespace pipeline {

namespace {

constexpr double kLidarHistogramRange_m = 0.3;
constexpr double kWhitenedHistogramRange = 5.0;  // sigma
// A block whose components never move by more than this (display units) between the outer
// iterations was held, unless the result carries its sigma.
constexpr double kUnchangedTolerance = 1e-9;
// Rotations: roll, pitch and yaw of R_I_L (the LiDAR in the IMU frame) and of R_V_I (the IMU
// in the vehicle frame), printed with this many decimals.
constexpr int kAngleDecimals = 2;
constexpr std::array<const char*, 3> kLidarAngleNames = {"T_I_L roll (about the IMU x axis)",
                                                         "T_I_L pitch (about the IMU y axis)",
                                                         "T_I_L yaw (about the IMU z axis)"};
constexpr std::array<const char*, 3> kMountAngleNames = {
    "IMU mount roll (about the vehicle's forward axis)",
    "IMU mount pitch (about the vehicle's left axis)",
    "IMU mount yaw (about the vehicle's up axis)"};

// "1 keyframe", "2 keyframes".
std::string Counted(size_t count, const std::string& noun) {
  return std::to_string(count) + " " + noun + (count == 1 ? "" : "s");
}

std::string SensorName(const std::string& key) {
  if (key == "imu") return "IMU";
  if (key == "wheel") return "Wheel odometry";
  if (key == "gnss") return "GNSS";
  if (key == "planar_rotation") return "Planar rotation (Eq. F27)";
  return key;
}

// The whitened sensors in a fixed order (IMU, wheel, GNSS, then any other in name order),
// those with at least one residual only.
std::vector<std::string> SensorsWithResiduals(const std::map<std::string, SensorResiduals>& all) {
  std::vector<std::string> keys;
  for (const char* known : {"imu", "wheel", "gnss"}) {
    if (all.count(known)) keys.push_back(known);
  }
  for (const auto& [key, residuals] : all) {
    if (key != "imu" && key != "wheel" && key != "gnss") keys.push_back(key);
  }
  keys.erase(std::remove_if(keys.begin(), keys.end(),
                            [&](const std::string& key) {
                              const SensorResiduals& r = all.at(key);
                              return r.before.empty() && r.after.empty();
                            }),
             keys.end());
  return keys;
}

// The change of block `info` from the first outer iteration to `c`, in display units (Eq.
// R3): Log(q_1^-1 q_k) for a rotation (about the block's own axes, the right perturbation),
// the difference otherwise.
std::vector<double> ChangeFromFirst(const sensors::CalibrationBlockInfo& info,
                                    const sensors::Calibration& first,
                                    const sensors::Calibration& c) {
  const double* v1 = info.const_values(first);
  const double* vk = info.const_values(c);
  Eigen::VectorXd change(info.tangent_size);
  if (info.manifold == sensors::BlockManifold::kRightQuaternion) {
    const Eigen::Quaterniond q1(v1[3], v1[0], v1[1], v1[2]), qk(vk[3], vk[0], vk[1], vk[2]);
    change = geometry::Log(Eigen::Quaterniond(q1.conjugate() * qk));
  } else {
    for (int i = 0; i < info.tangent_size; ++i) change(i) = vk[i] - v1[i];
  }
  change *= info.display_scale;
  return std::vector<double>(change.data(), change.data() + change.size());
}

// One chart of `info`'s change over the outer iterations, or "" when the block neither moved
// nor carries a sigma (it was held).
std::string BlockChart(const sensors::CalibrationBlockInfo& info,
                       const std::vector<sensors::Calibration>& history, bool has_sigma) {
  const char* colors[3] = {"#c33", "#3a3", "#36c"};
  std::vector<Series> series;
  for (int j = 0; j < info.tangent_size; ++j) {
    Series s{info.direction_names[static_cast<size_t>(j)], colors[j % 3], {}, {}};
    s.markers = true;
    series.push_back(s);
  }
  bool changed = false;
  for (size_t i = 0; i < history.size(); ++i) {
    const std::vector<double> change = ChangeFromFirst(info, history.front(), history[i]);
    for (size_t j = 0; j < change.size(); ++j) {
      series[j].x.push_back(static_cast<double>(i + 1));
      series[j].y.push_back(change[j]);
      changed = changed || std::abs(change[j]) > kUnchangedTolerance;
    }
  }
  if (!changed && !has_sigma) return "";
  const std::string unit = info.display_unit;
  return LineChart(std::string(info.name) + " (" + unit + ")", "outer iteration",
                   "change (" + unit + ")", series);
}

// The convergence section: one chart per estimated block, or a sentence saying why none.
std::string ConvergenceSection(const OfflineCalibrationResult& result) {
  const std::vector<sensors::Calibration>& history = result.batch.calibration_per_iteration;
  std::ostringstream html;
  html << "<h2>Convergence</h2>";
  if (history.size() < 2) {
    html << "<p>"
         << (history.empty() ? "No outer iteration was recorded"
                             : "Only one outer iteration was recorded")
         << ": no convergence chart.</p>\n";
    return html.str();
  }
  html << "<p>Change of each estimated block from the first outer iteration.</p>\n";
  int charts = 0;
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    const bool has_sigma =
        io::UncertaintyIn(result.calibration.uncertainty, info.id).sigma.has_value();
    const std::string chart = BlockChart(info, history, has_sigma);
    html << chart;
    if (!chart.empty()) ++charts;
  }
  if (charts == 0) html << "<p>No calibration block was estimated.</p>\n";
  return html.str();
}

// One flag for the whole block or one per component (io::PoseBlockInfo, VectorBlockInfo);
// none means observable. A block without sigma was not estimated (the problem fixes it): it
// is "fixed", whatever flags it carries.
std::string Observable(bool estimated, const std::vector<bool>& flags, size_t index) {
  if (!estimated) return "fixed";
  if (flags.empty()) return "yes";
  if (flags.size() != 1 && index >= flags.size()) return "–";
  const bool value = flags.size() == 1 ? flags[0] : flags[index];
  return value ? "yes" : "<b>no</b>";
}

// The LiDAR took part when the batch associated points with planes.
bool LidarUsed(const estimation::LidarInertialBatchReport& batch) {
  return batch.associated_points > 0 || !batch.initial_point_residuals_m.empty() ||
         !batch.final_point_residuals_m.empty();
}

// The displayed values of a block: a rotation as the roll, pitch and yaw (deg) of the mounting
// it stands for (mount_angles.h), anything else in its display unit.
Eigen::VectorXd DisplayValues(const sensors::CalibrationBlockInfo& info,
                              const sensors::Calibration& c) {
  const double* v = info.const_values(c);
  if (info.manifold != sensors::BlockManifold::kRightQuaternion) {
    return Eigen::Map<const Eigen::VectorXd>(v, info.ambient_size) * info.display_scale;
  }
  return DisplayRollPitchYawDeg(DisplayedMount(info, c), kAngleDecimals);
}

// A row's label: the mounting's angle for a rotation, else the block's name, axis and unit.
std::string RowLabel(const sensors::CalibrationBlockInfo& info, int k) {
  const size_t axis = static_cast<size_t>(k);
  if (info.manifold == sensors::BlockManifold::kRightQuaternion) {
    const bool vehicle = info.id == sensors::CalibrationBlockId::kVehicleRotation;
    return std::string((vehicle ? kMountAngleNames : kLidarAngleNames)[axis]) + " (deg)";
  }
  const char* axes[3] = {"x", "y", "z"};
  const std::string name =
      info.tangent_size == 1 ? info.name : std::string(info.name) + " " + axes[axis];
  return name + " (" + info.display_unit + ")";
}

// The result table: value, sigma, nominal and observability of each reported block, in the
// block table's order: the LiDAR's blocks whenever the LiDAR took part (a fixed one with
// sigma "–" and "fixed"), the others when the result carries their sigma (they were
// estimated).
std::string SummaryTable(const OfflineCalibrationResult& result, bool lidar_used) {
  std::ostringstream rows;
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    const io::BlockUncertainty u = io::UncertaintyIn(result.calibration.uncertainty, info.id);
    if (!u.sigma && !(lidar_used && info.sensor == sensors::BlockSensor::kLidar)) continue;
    const Eigen::VectorXd value = DisplayValues(info, result.calibration.value);
    const Eigen::VectorXd nominal = DisplayValues(info, result.nominal);
    const bool rotation = info.manifold == sensors::BlockManifold::kRightQuaternion;
    std::optional<Eigen::VectorXd> sigma;
    std::vector<bool> observable = u.observable;
    if (u.sigma) sigma = *u.sigma * (rotation ? 1.0 : info.display_scale);
    if (u.sigma && rotation) {  // the angles' own sigma and flags (mount_angles.h)
      const DisplayedAngles angles = DisplayedAngleUncertainty(
          DisplayedMount(info, result.calibration.value),
          info.id == sensors::CalibrationBlockId::kVehicleRotation, *u.sigma, u.observable);
      sigma = angles.sigma_deg;
      observable = angles.observable;
    }
    for (int k = 0; k < info.tangent_size; ++k) {
      rows << "<tr><td>" << RowLabel(info, k) << "</td><td>"
           << (rotation ? FormatFixed(value(k), kAngleDecimals) : Number(value(k))) << "</td><td>"
           << (sigma ? Number((*sigma)(k)) : "–") << "</td><td>"
           << (rotation ? FormatFixed(nominal(k), kAngleDecimals) : Number(nominal(k)))
           << "</td><td>" << Observable(u.sigma.has_value(), observable, static_cast<size_t>(k))
           << "</td></tr>";
    }
  }
  const std::string body = rows.str();
  if (body.empty()) return "<h2>Result</h2><p>No calibration block was estimated.</p>\n";
  return "<h2>Result</h2><table><tr><th>parameter</th><th>estimate</th><th>σ</th>"
         "<th>nominal</th><th>observable</th></tr>" +
         body + "</table>\n";
}

// One paragraph on the solve and one line per sensor: what took part and with how many
// residuals.
std::string RunSummary(const OfflineCalibrationResult& result, bool lidar_used,
                       const std::vector<std::string>& whitened_sensors) {
  std::vector<std::string> facts;
  if (result.batch.outer_iterations > 0) {
    facts.push_back(Counted(static_cast<size_t>(result.batch.outer_iterations), "outer iteration") +
                    (result.batch.converged ? "" : " (stopped before converging)"));
  }
  facts.push_back(Counted(result.trajectory.size(), "keyframe"));
  if (std::isfinite(result.seconds_total) && result.seconds_total > 0.0) {
    facts.push_back(Number(result.seconds_total) + " s");
  }
  std::ostringstream html;
  html << "<p>";
  for (size_t i = 0; i < facts.size(); ++i) html << (i ? ", " : "") << facts[i];
  html << '.';
  if (!result.batch.termination.empty()) {
    html << " Solver: " << Escape(result.batch.termination);
  }
  html << "</p>\n<ul class='sensors'><li>LiDAR: ";
  if (lidar_used) {
    const size_t points = result.batch.associated_points > 0
                              ? static_cast<size_t>(result.batch.associated_points)
                              : result.batch.final_point_residuals_m.size();
    html << Counted(points, "point residual") << " in the last iteration";
    if (result.batch.points_downweighted_by_loss > 0) {
      html << "; the robust loss down-weighted " << result.batch.points_downweighted_by_loss
           << " (the others' RMS " << Number(result.batch.point_rms_not_downweighted_m * 100.0)
           << " cm)";
    }
  } else {
    html << "not used";
  }
  html << "</li>";
  for (const std::string& key : whitened_sensors) {
    const SensorResiduals& r = result.whitened_residuals.at(key);
    html << "<li>" << Escape(SensorName(key)) << ": "
         << Counted(std::max(r.before.size(), r.after.size()), "whitened residual row");
    if (r.factors_downweighted > 0) {
      html << "; the robust loss down-weighted " << r.factors_downweighted << " of "
           << Counted(r.factors, "factor") << " (the others' RMS " << Number(r.rms_not_downweighted)
           << ")";
    }
    html << "</li>";
  }
  if (!result.gnss_positions_W.empty()) {
    html << "<li>GNSS fixes: " << result.gnss_positions_W.size() << "</li>";
  }
  html << "</ul>\n";
  return html.str();
}

// A heading and its chart, or nothing when the chart has no data.
std::string Section(const std::string& heading, const std::string& chart) {
  return chart.empty() ? "" : "<h2>" + Escape(heading) + "</h2>" + chart;
}

std::string ResidualSection(const OfflineCalibrationResult& result, bool lidar_used,
                            const std::vector<std::string>& whitened_sensors) {
  std::string html;
  if (lidar_used) {
    html +=
        Section("LiDAR residuals",
                ResidualHistogram("point-to-plane distance, before and after the solve",
                                  "distance (m)", "points per bin (%)", "m", kLidarHistogramRange_m,
                                  result.batch.initial_point_residuals_m,
                                  result.batch.final_point_residuals_m, false));
  }
  for (const std::string& key : whitened_sensors) {
    const SensorResiduals& r = result.whitened_residuals.at(key);
    const std::string name = SensorName(key);
    html += Section(name + " residuals",
                    ResidualHistogram(name + " whitened residuals, before and after the solve",
                                      "residual (σ)", "rows per bin (%)", "σ",
                                      kWhitenedHistogramRange, r.before, r.after, true));
  }
  return html;
}

// One cross-correlation curve against the candidate offsets, in ms; empty without one.
std::string CorrelationChart(const std::string& title, const std::vector<double>& offsets_s,
                             const std::vector<double>& correlation) {
  if (offsets_s.empty() || offsets_s.size() != correlation.size()) return "";
  Series curve{"correlation", "#36c", {}, {}};
  for (size_t i = 0; i < offsets_s.size(); ++i) {
    curve.x.push_back(offsets_s[i] * 1e3);
    curve.y.push_back(correlation[i]);
  }
  return LineChart(title, "candidate offset (ms)", "correlation", {curve});
}

// The candidate offset (s) where `correlation` is largest; 0 without a finite value.
double CurvePeak(const std::vector<double>& offsets_s, const std::vector<double>& correlation) {
  double peak_s = 0.0, best = -std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < offsets_s.size() && i < correlation.size(); ++i) {
    if (std::isfinite(correlation[i]) && correlation[i] > best) {
      best = correlation[i];
      peak_s = offsets_s[i];
    }
  }
  return peak_s;
}

// The LiDAR curve's caption: its peak (refined, when the initializer took it; otherwise the
// curve's largest value, as the offset then holds the value the solve started from instead)
// and, when that peak did not start the solve, why.
std::string LidarClockCaption(const OfflineCalibrationResult& result) {
  const estimation::TimeOffsetEstimate& lidar = result.initialization.time_offset;
  const double peak_s =
      lidar.reliable ? lidar.offset_s : CurvePeak(lidar.candidate_offsets_s, lidar.correlation);
  std::string not_used;
  if (!lidar.reliable) {
    not_used =
        ", not used: " + (lidar.reason.empty() ? std::string("not determined") : lidar.reason);
  } else if (!result.calibration.uncertainty.time_offset_lidar_imu_s.sigma) {
    not_used = ", not used: the problem fixes the LiDAR-IMU time offset";
  } else if (result.lidar_blocks_from_nominal) {
    not_used =
        ", not used: the keyframes were rebuilt from GNSS and the IMU, and the offset started "
        "from its nominal value";
  }
  return "LiDAR vs gyro angular-rate correlation (peak " + Number(peak_s * 1e3) + " ms" + not_used +
         ")";
}

// The clocks' initializations: the LiDAR's against the gyro, the wheels' and the GNSS
// receiver's (t_imu = t_sensor + offset), each the curve whose peak started the solve.
std::string ClockSection(const OfflineCalibrationResult& result) {
  const estimation::TimeOffsetEstimate& lidar = result.initialization.time_offset;
  std::string charts =
      CorrelationChart(LidarClockCaption(result), lidar.candidate_offsets_s, lidar.correlation);
  if (result.wheel_clock_initialization) {
    const estimation::SeriesOffsetEstimate& e = result.wheel_clock_initialization->estimate;
    charts += CorrelationChart("wheels vs IMU, " + result.wheel_clock_initialization->signal +
                                   " (peak " + Number(e.offset_s * 1e3) + " ms" +
                                   (e.reliable ? "" : ", not used: " + e.reason) + ")",
                               e.candidate_offsets_s, e.correlation);
  }
  if (result.gnss_clock_initialization) {
    const estimation::SeriesOffsetEstimate& e = *result.gnss_clock_initialization;
    charts += CorrelationChart("GNSS track speed vs wheel speed (peak " + Number(e.offset_s * 1e3) +
                                   " ms" + (e.reliable ? "" : ", not used: " + e.reason) + ")",
                               e.candidate_offsets_s, e.correlation);
  }
  return Section("Clock offset initialization", charts);
}

// A position's covariance from a block's per-axis sigma in the IMU frame, turned into V.
Eigen::Matrix3d CovarianceInV(const Eigen::Matrix3d& R_V_I,
                              const std::optional<Eigen::Vector3d>& sigma_I) {
  if (!sigma_I) return Eigen::Matrix3d::Zero();
  return R_V_I * sigma_I->cwiseAbs2().asDiagonal() * R_V_I.transpose();
}

struct RigPoint {
  std::string label;
  std::string color;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
};

// The sensors in the vehicle frame (docs/report.md, "Rig"): its origin (the rear-axle centre),
// the IMU at p_V_I with the rear axle's translation sigma, the LiDAR and the antenna at T_V_I p
// with their own sigma added, the rear wheels at +-track/2 with half the track's sigma.
// Without an estimated mount the IMU frame stands in for V.
std::vector<RigPoint> RigPoints(const OfflineCalibrationResult& result, bool lidar_used) {
  const sensors::Calibration& c = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  const bool vehicle = u.T_I_V.sigma_rot_deg.has_value();
  const geometry::Pose3d T_V_I =
      vehicle ? geometry::Pose3d(c.q_I_V, c.p_I_V).Inverse() : geometry::Pose3d::Identity();
  const Eigen::Matrix3d R_V_I = T_V_I.R();
  const Eigen::Matrix3d imu_cov =
      vehicle ? CovarianceInV(R_V_I, u.T_I_V.sigma_p_m) : Eigen::Matrix3d::Zero();
  std::vector<RigPoint> points = {{"IMU", "#333", T_V_I.p, imu_cov}};
  if (vehicle) {
    points.push_back(
        {"rear axle centre", "#999", Eigen::Vector3d::Zero(), Eigen::Matrix3d::Zero()});
  }
  if (lidar_used || u.T_I_L.sigma_p_m) {
    points.push_back(
        {"LiDAR", "#36c", T_V_I * c.p_I_L, CovarianceInV(R_V_I, u.T_I_L.sigma_p_m) + imu_cov});
  }
  if (u.p_I_A_m.sigma) {
    points.push_back(
        {"GNSS antenna", "#c33", T_V_I * c.p_I_A, CovarianceInV(R_V_I, u.p_I_A_m.sigma) + imu_cov});
  }
  if (vehicle && u.track_width_m.sigma) {
    const double half = 0.5 * c.track_width_m;
    const double var = 0.25 * *u.track_width_m.sigma * *u.track_width_m.sigma;
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    cov(1, 1) = var;
    points.push_back({"left rear wheel", "#393", Eigen::Vector3d(0.0, half, 0.0), cov});
    points.push_back({"right rear wheel", "#393", Eigen::Vector3d(0.0, -half, 0.0), cov});
  }
  return points;
}

// The power of ten that makes the largest 1-sigma ellipse at least 2 % of the rig's extent.
double EllipseMagnification(const std::vector<RigPoint>& points) {
  double extent = 1.0, sigma = 0.0;
  for (const RigPoint& a : points) {
    for (const RigPoint& b : points) extent = std::max(extent, (a.p - b.p).norm());
    sigma = std::max(sigma, std::sqrt(std::max(a.covariance.diagonal().maxCoeff(), 0.0)));
  }
  double magnification = 1.0;
  while (sigma > 0.0 && magnification * sigma < 0.02 * extent && magnification < 1e6) {
    magnification *= 10.0;
  }
  return magnification;
}

std::string RigSection(const OfflineCalibrationResult& result, bool lidar_used) {
  const std::vector<RigPoint> points = RigPoints(result, lidar_used);
  if (points.size() < 2) return "";
  const bool vehicle = result.calibration.uncertainty.T_I_V.sigma_rot_deg.has_value();
  const double magnification = EllipseMagnification(points);
  const auto view = [&](int a, int b, const std::string& title, const std::string& x_label,
                        const std::string& y_label) {
    std::vector<RigMark> marks;
    for (const RigPoint& p : points) {
      Eigen::Matrix2d cov;
      cov << p.covariance(a, a), p.covariance(a, b), p.covariance(b, a), p.covariance(b, b);
      marks.push_back({p.label, p.color, p.p(a), p.p(b), cov});
    }
    return RigView(title, x_label, y_label, marks, magnification);
  };
  const std::string frame = vehicle ? "vehicle frame" : "IMU frame";
  return Section("Rig",
                 view(0, 1, "from above, " + frame, vehicle ? "forward x (m)" : "x (m)",
                      vehicle ? "left y (m)" : "y (m)") +
                     view(0, 2, "from the side, " + frame, vehicle ? "forward x (m)" : "x (m)",
                          vehicle ? "up z (m)" : "z (m)"));
}

std::string TrajectorySection(const OfflineCalibrationResult& result) {
  Series top{"keyframes", "#333", {}, {}};
  for (const io::TrajectorySample& s : result.trajectory) {
    top.x.push_back(s.T_W_I.p.x());
    top.y.push_back(s.T_W_I.p.y());
  }
  std::vector<Series> trajectory = {top};
  if (!result.gnss_positions_W.empty()) {
    Series fixes{"GNSS fixes (incl. outliers)", "#c33", {}, {}, true};
    for (const Eigen::Vector3d& p : result.gnss_positions_W) {
      fixes.x.push_back(p.x());
      fixes.y.push_back(p.y());
    }
    trajectory.insert(trajectory.begin(), fixes);
  }
  const std::string chart =
      LineChart(result.gnss_positions_W.empty() ? "IMU trajectory from above"
                                                : "IMU trajectory against GNSS (ENU)",
                "east (m)", "north (m)", trajectory, true);
  return Section("Trajectory", chart);
}

}  // namespace

std::string CalibrationReportHtml(const OfflineCalibrationResult& result) {
  const bool lidar_used = LidarUsed(result.batch);
  const std::vector<std::string> whitened_sensors = SensorsWithResiduals(result.whitened_residuals);
  std::ostringstream html;
  html << HtmlPageStart("autocal calibration report");
  html << SummaryTable(result, lidar_used) << RunSummary(result, lidar_used, whitened_sensors);
  html << HtmlWarnings("Warnings", result.warnings);
  html << BoundSection(result);
  html << ResidualSection(result, lidar_used, whitened_sensors) << ConvergenceSection(result)
       << ClockSection(result) << RigSection(result, lidar_used) << TrajectorySection(result);
  html << HtmlPageEnd();
  return html.str();
}

}  // namespace pipeline
}  // namespace autocal
