#include "autocal/pipeline/report_html.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <vector>

#include "autocal/geometry/so3.h"

namespace autocal {
namespace pipeline {

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
constexpr int kWidth = 560;
constexpr int kHeight = 260;
constexpr int kMargin = 48;

std::string Escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '&': out += "&amp;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

struct Series {
  std::string label;
  std::string color;
  std::vector<double> x, y;
  bool dots = false;  // points instead of a line
};

// Maps data ranges onto the plot area (y up).
struct Axes {
  double x0, x1, y0, y1;
  double X(double x) const {
    return kMargin + (x - x0) / (x1 - x0) * (kWidth - 2 * kMargin);
  }
  double Y(double y) const {
    return kHeight - kMargin + (y0 - y) / (y1 - y0) * (kHeight - 2 * kMargin);
  }
};

Axes Fit(const std::vector<Series>& series, bool equal_scale) {
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const Series& s : series) {
    for (double x : s.x) { x0 = std::min(x0, x); x1 = std::max(x1, x); }
    for (double y : s.y) { y0 = std::min(y0, y); y1 = std::max(y1, y); }
  }
  if (!(x1 > x0)) { x0 -= 1.0; x1 += 1.0; }
  if (!(y1 > y0)) { y0 -= 1.0; y1 += 1.0; }
  if (equal_scale) {
    const double sx = (x1 - x0) / (kWidth - 2 * kMargin);
    const double sy = (y1 - y0) / (kHeight - 2 * kMargin);
    const double s = std::max(sx, sy);
    const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
    x0 = cx - 0.5 * s * (kWidth - 2 * kMargin);
    x1 = cx + 0.5 * s * (kWidth - 2 * kMargin);
    y0 = cy - 0.5 * s * (kHeight - 2 * kMargin);
    y1 = cy + 0.5 * s * (kHeight - 2 * kMargin);
  }
  return {x0, x1, y0, y1};
}

std::string Number(double v) {
  std::ostringstream out;
  out << std::setprecision(4) << v;
  return out.str();
}

// A line chart with axis labels and a legend.
std::string LineChart(const std::string& title, const std::string& x_label,
                      const std::string& y_label, const std::vector<Series>& series,
                      bool equal_scale = false) {
  const Axes a = Fit(series, equal_scale);
  std::ostringstream svg;
  svg << "<figure><figcaption>" << Escape(title) << "</figcaption><svg width='" << kWidth
      << "' height='" << kHeight << "' viewBox='0 0 " << kWidth << ' ' << kHeight << "'>"
      << "<rect x='" << kMargin << "' y='" << kMargin << "' width='" << kWidth - 2 * kMargin
      << "' height='" << kHeight - 2 * kMargin << "' fill='none' stroke='#999'/>";
  svg << "<text x='" << kMargin << "' y='" << kHeight - kMargin + 16 << "'>" << Number(a.x0)
      << "</text><text x='" << kWidth - kMargin << "' y='" << kHeight - kMargin + 16
      << "' text-anchor='end'>" << Number(a.x1) << "</text><text x='" << kWidth / 2 << "' y='"
      << kHeight - 8 << "' text-anchor='middle'>" << Escape(x_label) << "</text>";
  svg << "<text x='" << kMargin - 4 << "' y='" << kHeight - kMargin
      << "' text-anchor='end'>" << Number(a.y0) << "</text><text x='" << kMargin - 4
      << "' y='" << kMargin + 10 << "' text-anchor='end'>" << Number(a.y1)
      << "</text><text x='12' y='" << kHeight / 2 << "' transform='rotate(-90 12 " << kHeight / 2
      << ")' text-anchor='middle'>" << Escape(y_label) << "</text>";
  int legend_y = kMargin + 14;
  for (const Series& s : series) {
    if (s.dots) {
      for (size_t i = 0; i < s.x.size(); ++i) {
        svg << "<circle r='1.5' fill='" << s.color << "' cx='" << std::fixed
            << std::setprecision(1) << a.X(s.x[i]) << "' cy='" << a.Y(s.y[i]) << "'/>";
      }
    } else {
      svg << "<polyline fill='none' stroke='" << s.color << "' stroke-width='1.5' points='";
      for (size_t i = 0; i < s.x.size(); ++i) {
        svg << std::fixed << std::setprecision(1) << a.X(s.x[i]) << ',' << a.Y(s.y[i]) << ' ';
      }
      svg << "'/>";
    }
    svg << "<text x='" << kWidth - kMargin - 6 << "' y='" << legend_y
        << "' text-anchor='end' fill='" << s.color << "'>" << Escape(s.label) << "</text>";
    legend_y += 14;
  }
  svg << "</svg></figure>\n";
  return svg.str();
}

// Histogram of values in [-range, range] as step lines, one per series (same bins).
std::string Histogram(const std::string& title, const std::string& x_label, double range,
                      const std::vector<std::pair<Series, std::vector<double>>>& inputs) {
  constexpr int kBins = 60;
  std::vector<Series> series;
  for (const auto& [style, values] : inputs) {
    Series s = style;
    std::vector<double> counts(kBins, 0.0);
    for (double v : values) {
      const int bin = static_cast<int>(std::floor((v + range) / (2.0 * range) * kBins));
      if (bin >= 0 && bin < kBins) counts[static_cast<size_t>(bin)] += 1.0;
    }
    const double total = std::max<double>(1.0, static_cast<double>(values.size()));
    for (int b = 0; b < kBins; ++b) {
      const double left = -range + 2.0 * range * b / kBins;
      const double right = left + 2.0 * range / kBins;
      s.x.push_back(left);
      s.y.push_back(counts[static_cast<size_t>(b)] / total);
      s.x.push_back(right);
      s.y.push_back(counts[static_cast<size_t>(b)] / total);
    }
    series.push_back(s);
  }
  return LineChart(title, x_label, "fraction of points", series);
}

double Rms(const std::vector<double>& values) {
  double sum = 0.0;
  for (double v : values) sum += v * v;
  return values.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(values.size()));
}

std::string Sigma(const std::optional<Eigen::Vector3d>& sigma, double scale, int row) {
  return sigma ? Number((*sigma)(row) * scale) : "–";
}

std::string Observable(const std::vector<bool>& flags, size_t index) {
  if (flags.empty()) return "yes";
  const bool value = flags.size() == 1 ? flags[0] : flags[index];
  return value ? "yes" : "<b>no</b>";
}

}  // namespace

std::string CalibrationReportHtml(const OfflineCalibrationResult& result) {
  const sensors::Calibration& c = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  std::ostringstream html;
  html << "<!DOCTYPE html><html><head><meta charset='utf-8'><title>autocal calibration report"
          "</title><style>body{font-family:sans-serif;max-width:1180px;margin:auto}"
          "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;"
          "text-align:right}figure{display:inline-block;margin:8px}svg text{font-size:11px}"
          ".warn{color:#a40}</style></head><body><h1>autocal calibration report</h1>\n";

  // Summary.
  html << "<h2>Result</h2><table><tr><th>parameter</th><th>estimate</th><th>σ</th>"
          "<th>nominal</th><th>observable</th></tr>";
  const Eigen::Vector3d rotation_deg = geometry::Log(c.q_I_L) * kRadToDeg;
  const Eigen::Vector3d nominal_rotation_deg = geometry::Log(result.nominal.q_I_L) * kRadToDeg;
  const char* axes[3] = {"x", "y", "z"};
  for (int i = 0; i < 3; ++i) {
    html << "<tr><td>T_I_L rotation vector " << axes[i] << " (deg)</td><td>"
         << Number(rotation_deg(i)) << "</td><td>" << Sigma(u.T_I_L.sigma_rot_deg, 1.0, i)
         << "</td><td>" << Number(nominal_rotation_deg(i)) << "</td><td>"
         << Observable(u.T_I_L.observable, static_cast<size_t>(i)) << "</td></tr>";
  }
  for (int i = 0; i < 3; ++i) {
    html << "<tr><td>T_I_L translation " << axes[i] << " (m)</td><td>" << Number(c.p_I_L(i))
         << "</td><td>" << Sigma(u.T_I_L.sigma_p_m, 1.0, i) << "</td><td>"
         << Number(result.nominal.p_I_L(i)) << "</td><td>"
         << Observable(u.T_I_L.observable, static_cast<size_t>(3 + i)) << "</td></tr>";
  }
  html << "<tr><td>time offset lidar→imu (ms)</td><td>" << Number(c.time_offset_lidar_imu_s * 1e3)
       << "</td><td>"
       << (u.time_offset_lidar_imu_s.sigma ? Number(*u.time_offset_lidar_imu_s.sigma * 1e3) : "–")
       << "</td><td>" << Number(result.nominal.time_offset_lidar_imu_s * 1e3) << "</td><td>"
       << (u.time_offset_lidar_imu_s.observable.value_or(true) ? "yes" : "<b>no</b>")
       << "</td></tr>";
  // Wheel and GNSS blocks: shown when the result carries their sigma (they were estimated).
  const auto scalar_row = [&](const std::string& label, double value, double nominal,
                              const io::ScalarBlockInfo& info, double scale) {
    if (!info.sigma) return;
    html << "<tr><td>" << label << "</td><td>" << Number(value * scale) << "</td><td>"
         << Number(*info.sigma * scale) << "</td><td>" << Number(nominal * scale) << "</td><td>"
         << (info.observable.value_or(true) ? "yes" : "<b>no</b>") << "</td></tr>";
  };
  scalar_row("wheel radius left (mm)", c.wheel_radius_left_m, result.nominal.wheel_radius_left_m,
             u.wheel_radius_left_m, 1e3);
  scalar_row("wheel radius right (mm)", c.wheel_radius_right_m,
             result.nominal.wheel_radius_right_m, u.wheel_radius_right_m, 1e3);
  scalar_row("track width (mm)", c.track_width_m, result.nominal.track_width_m, u.track_width_m,
             1e3);
  if (u.p_I_A_m.sigma) {
    for (int i = 0; i < 3; ++i) {
      html << "<tr><td>GNSS lever arm " << axes[i] << " (m)</td><td>" << Number(c.p_I_A(i))
           << "</td><td>" << Number((*u.p_I_A_m.sigma)(i)) << "</td><td>"
           << Number(result.nominal.p_I_A(i)) << "</td><td>"
           << Observable(u.p_I_A_m.observable, static_cast<size_t>(i)) << "</td></tr>";
    }
  }
  if (u.T_I_V.sigma_rot_deg || u.T_I_V.sigma_p_m) {
    const Eigen::Vector3d v_deg = geometry::Log(c.q_I_V) * kRadToDeg;
    const Eigen::Vector3d v_nominal_deg = geometry::Log(result.nominal.q_I_V) * kRadToDeg;
    for (int i = 0; i < 3; ++i) {
      html << "<tr><td>T_I_V rotation vector " << axes[i] << " (deg)</td><td>"
           << Number(v_deg(i)) << "</td><td>" << Sigma(u.T_I_V.sigma_rot_deg, 1.0, i)
           << "</td><td>" << Number(v_nominal_deg(i)) << "</td><td>"
           << Observable(u.T_I_V.observable, static_cast<size_t>(i)) << "</td></tr>";
    }
    for (int i = 0; i < 3; ++i) {
      html << "<tr><td>T_I_V translation " << axes[i] << " (m)</td><td>" << Number(c.p_I_V(i))
           << "</td><td>" << Sigma(u.T_I_V.sigma_p_m, 1.0, i) << "</td><td>"
           << Number(result.nominal.p_I_V(i)) << "</td><td>"
           << Observable(u.T_I_V.observable, static_cast<size_t>(3 + i)) << "</td></tr>";
    }
  }
  html << "</table>\n";
  html << "<p>" << result.batch.outer_iterations << " outer iterations, "
       << result.trajectory.size() << " keyframes, " << result.batch.associated_points
       << " LiDAR residuals, " << Number(result.seconds_total) << " s. Solver: "
       << Escape(result.batch.termination) << "</p>\n";
  if (!result.warnings.empty()) {
    html << "<h2>Warnings</h2><ul>";
    for (const std::string& w : result.warnings) html << "<li class='warn'>" << Escape(w) << "</li>";
    html << "</ul>\n";
  }

  // Residuals.
  html << "<h2>LiDAR residuals</h2>";
  Series before{"before (RMS " + Number(Rms(result.batch.initial_point_residuals_m)) + " m)",
                "#c33", {}, {}};
  Series after{"after (RMS " + Number(Rms(result.batch.final_point_residuals_m)) + " m)",
               "#36c", {}, {}};
  html << Histogram("point-to-plane distance, before and after the solve", "distance (m)", 0.3,
                    {{before, result.batch.initial_point_residuals_m},
                     {after, result.batch.final_point_residuals_m}});

  // Convergence.
  html << "<h2>Convergence</h2>";
  Series rotation{"rotation change from start (deg)", "#c33", {}, {}};
  Series translation{"translation change from start (cm)", "#3a3", {}, {}};
  Series offset{"time offset (ms)", "#36c", {}, {}};
  const std::vector<sensors::Calibration>& history = result.batch.calibration_per_iteration;
  for (size_t i = 0; i < history.size(); ++i) {
    const double x = static_cast<double>(i + 1);
    rotation.x.push_back(x);
    rotation.y.push_back(geometry::AngularDistance(history[i].q_I_L, history.front().q_I_L) *
                         kRadToDeg);
    translation.x.push_back(x);
    translation.y.push_back((history[i].p_I_L - history.front().p_I_L).norm() * 100.0);
    offset.x.push_back(x);
    offset.y.push_back(history[i].time_offset_lidar_imu_s * 1e3);
  }
  html << LineChart("extrinsic per outer iteration", "outer iteration", "", {rotation, translation});
  html << LineChart("time offset per outer iteration", "outer iteration", "ms", {offset});

  // Time offset correlation.
  const estimation::TimeOffsetEstimate& t = result.initialization.time_offset;
  if (!t.candidate_offsets_s.empty()) {
    Series curve{"correlation", "#36c", {}, {}};
    for (size_t i = 0; i < t.candidate_offsets_s.size(); ++i) {
      curve.x.push_back(t.candidate_offsets_s[i] * 1e3);
      curve.y.push_back(t.correlation[i]);
    }
    html << "<h2>Time offset initialization</h2>"
         << LineChart("LiDAR vs gyro angular-rate correlation (peak " +
                          Number(t.offset_s * 1e3) + " ms)",
                      "candidate offset (ms)", "correlation", {curve});
  }

  // Trajectory.
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
  html << "<h2>Trajectory</h2>"
       << LineChart(result.gnss_positions_W.empty() ? "IMU trajectory from above"
                                                     : "IMU trajectory against GNSS (ENU)",
                    "east (m)", "north (m)", trajectory, true);
  html << "</body></html>\n";
  return html.str();
}

}  // namespace pipeline
}  // namespace autocal
