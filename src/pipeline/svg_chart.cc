#include "svg_chart.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <utility>

#include "autocal/common/format.h"
#include "autocal/common/units.h"

namespace autocal {
namespace pipeline {

std::string Escape(const std::string& text) { return EscapeXml(text); }

std::string Number(double v) {
  if (!std::isfinite(v)) return "–";
  std::ostringstream out;
  out << std::setprecision(4) << v;
  return out.str();
}

namespace {

constexpr int kWidth = 560;
constexpr int kHeight = 260;
// Plot area inside the chart; the legend sits in the band above it (up to three lines).
constexpr int kPlotLeft = 64;
constexpr int kPlotRight = kWidth - 24;
constexpr int kPlotTop = 48;
constexpr int kPlotBottom = kHeight - 40;
constexpr int kPlotWidth = kPlotRight - kPlotLeft;
constexpr int kPlotHeight = kPlotBottom - kPlotTop;
constexpr int kHistogramBins = 60;

std::string Percent(double fraction) { return Number(100.0 * fraction) + " %"; }

// Maps data ranges onto the plot area (y up).
struct Axes {
  double x0, x1, y0, y1;
  double X(double x) const { return kPlotLeft + (x - x0) / (x1 - x0) * kPlotWidth; }
  double Y(double y) const { return kPlotBottom + (y0 - y) / (y1 - y0) * kPlotHeight; }
};

bool FinitePoint(const Series& s, size_t i) {
  return std::isfinite(s.x[i]) && std::isfinite(s.y[i]);
}

// The range of the finite points; false when there are none.
bool Fit(const std::vector<Series>& series, bool equal_scale, Axes* axes) {
  double x0 = HUGE_VAL, x1 = -HUGE_VAL, y0 = HUGE_VAL, y1 = -HUGE_VAL;
  for (const Series& s : series) {
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!FinitePoint(s, i)) continue;
      x0 = std::min(x0, s.x[i]);
      x1 = std::max(x1, s.x[i]);
      y0 = std::min(y0, s.y[i]);
      y1 = std::max(y1, s.y[i]);
    }
  }
  if (x0 > x1) return false;
  if (!(x1 > x0)) {
    x0 -= 1.0;
    x1 += 1.0;
  }
  if (!(y1 > y0)) {
    y0 -= 1.0;
    y1 += 1.0;
  }
  if (equal_scale) {
    const double sx = (x1 - x0) / kPlotWidth;
    const double sy = (y1 - y0) / kPlotHeight;
    const double s = std::max(sx, sy);
    const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
    x0 = cx - 0.5 * s * kPlotWidth;
    x1 = cx + 0.5 * s * kPlotWidth;
    y0 = cy - 0.5 * s * kPlotHeight;
    y1 = cy + 0.5 * s * kPlotHeight;
  }
  *axes = {x0, x1, y0, y1};
  return true;
}

// Statistics of one residual set over its finite values (docs/report.md, Eq. R1).
struct ResidualStats {
  size_t count = 0;  // finite values
  double rms = 0.0;
  double beyond_range = 0.0;  // share of the finite values with |r| > range
};

ResidualStats Statistics(const std::vector<double>& values, double range) {
  ResidualStats stats;
  double sum_sq = 0.0;
  size_t beyond = 0;
  for (double v : values) {
    if (!std::isfinite(v)) continue;
    ++stats.count;
    sum_sq += v * v;
    if (std::abs(v) > range) ++beyond;
  }
  if (stats.count > 0) {
    const double n = static_cast<double>(stats.count);
    stats.rms = std::sqrt(sum_sq / n);
    stats.beyond_range = static_cast<double>(beyond) / n;
  }
  return stats;
}

// Step line of the share of values (percent) per bin of [-range, range], so that series of
// different sizes compare.
Series HistogramSeries(const std::string& label, const std::string& color,
                       const std::vector<double>& values, double range, size_t count) {
  std::vector<double> counts(kHistogramBins, 0.0);
  for (double v : values) {
    if (!std::isfinite(v)) continue;
    const double bin = std::floor((v + range) / (2.0 * range) * kHistogramBins);
    if (bin >= 0.0 && bin < kHistogramBins) counts[static_cast<size_t>(bin)] += 1.0;
  }
  Series s{label, color, {}, {}};
  const double width = 2.0 * range / kHistogramBins;
  for (int b = 0; b < kHistogramBins; ++b) {
    const double share = 100.0 * counts[static_cast<size_t>(b)] / static_cast<double>(count);
    s.x.insert(s.x.end(), {-range + width * b, -range + width * (b + 1)});
    s.y.insert(s.y.end(), {share, share});
  }
  return s;
}

// The figure's opening: caption, the plot's frame, the axis ranges and labels.
void OpenFigure(const std::string& title, const std::string& x_label, const std::string& y_label,
                const Axes& a, std::ostringstream& svg) {
  svg << "<figure><figcaption>" << Escape(title) << "</figcaption><svg width='" << kWidth
      << "' height='" << kHeight << "' viewBox='0 0 " << kWidth << ' ' << kHeight << "'>"
      << "<rect x='" << kPlotLeft << "' y='" << kPlotTop << "' width='" << kPlotWidth
      << "' height='" << kPlotHeight << "' fill='none' stroke='#999'/>";
  svg << "<text x='" << kPlotLeft << "' y='" << kPlotBottom + 14 << "'>" << Number(a.x0)
      << "</text><text x='" << kPlotRight << "' y='" << kPlotBottom + 14 << "' text-anchor='end'>"
      << Number(a.x1) << "</text><text x='" << kPlotLeft + kPlotWidth / 2 << "' y='" << kHeight - 8
      << "' text-anchor='middle'>" << Escape(x_label) << "</text>";
  svg << "<text x='" << kPlotLeft - 4 << "' y='" << kPlotBottom << "' text-anchor='end'>"
      << Number(a.y0) << "</text><text x='" << kPlotLeft - 4 << "' y='" << kPlotTop + 10
      << "' text-anchor='end'>" << Number(a.y1) << "</text><text x='12' y='"
      << kPlotTop + kPlotHeight / 2 << "' transform='rotate(-90 12 " << kPlotTop + kPlotHeight / 2
      << ")' text-anchor='middle'>" << Escape(y_label) << "</text>";
}

}  // namespace

std::string LineChart(const std::string& title, const std::string& x_label,
                      const std::string& y_label, const std::vector<Series>& series,
                      bool equal_scale) {
  Axes a{};
  if (!Fit(series, equal_scale, &a)) return "";
  std::ostringstream svg;
  OpenFigure(title, x_label, y_label, a, svg);
  svg << std::fixed << std::setprecision(1);
  if (a.y0 < 0.0 && a.y1 > 0.0) {
    svg << "<line x1='" << kPlotLeft << "' x2='" << kPlotRight << "' y1='" << a.Y(0.0) << "' y2='"
        << a.Y(0.0) << "' stroke='#ccc'/>";
  }
  int legend_y = 12;
  for (const Series& s : series) {
    if (s.dots || s.markers) {
      for (size_t i = 0; i < s.x.size(); ++i) {
        if (!FinitePoint(s, i)) continue;
        svg << "<circle r='" << (s.markers ? 2.5 : 1.5) << "' fill='" << s.color << "' cx='"
            << a.X(s.x[i]) << "' cy='" << a.Y(s.y[i]) << "'/>";
      }
    }
    if (!s.dots) {
      svg << "<polyline fill='none' stroke='" << s.color << "' stroke-width='1.5'"
          << (s.dashed ? " stroke-dasharray='4 3'" : "") << " points='";
      for (size_t i = 0; i < s.x.size(); ++i) {
        if (FinitePoint(s, i)) svg << a.X(s.x[i]) << ',' << a.Y(s.y[i]) << ' ';
      }
      svg << "'/>";
    }
    svg << "<text x='" << kPlotRight << "' y='" << legend_y << "' text-anchor='end' fill='"
        << s.color << "'>" << Escape(s.label) << "</text>";
    legend_y += 14;
  }
  svg << "</svg></figure>\n";
  return svg.str();
}

std::string RigView(const std::string& title, const std::string& x_label,
                    const std::string& y_label, const std::vector<RigMark>& marks,
                    double magnification) {
  // The frame holds every dot and its magnified ellipse's bounding box.
  Series extent{"", "", {}, {}};
  for (const RigMark& m : marks) {
    if (!std::isfinite(m.x) || !std::isfinite(m.y) || !m.covariance.allFinite()) continue;
    const double hx = magnification * std::sqrt(std::max(m.covariance(0, 0), 0.0));
    const double hy = magnification * std::sqrt(std::max(m.covariance(1, 1), 0.0));
    extent.x.insert(extent.x.end(), {m.x - hx - 0.2, m.x + hx + 0.2});
    extent.y.insert(extent.y.end(), {m.y - hy - 0.2, m.y + hy + 0.2});
  }
  Axes a{};
  if (!Fit({extent}, true, &a)) return "";
  const double pixels_per_m = kPlotWidth / (a.x1 - a.x0);
  std::ostringstream svg;
  OpenFigure(title + (magnification > 1.0 ? " (1σ ellipses ×" + Number(magnification) + ")"
                                          : " (1σ ellipses)"),
             x_label, y_label, a, svg);
  svg << std::fixed << std::setprecision(1);
  for (const RigMark& m : marks) {
    if (!std::isfinite(m.x) || !std::isfinite(m.y) || !m.covariance.allFinite()) continue;
    const double cx = a.X(m.x), cy = a.Y(m.y);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(m.covariance);
    const Eigen::Vector2d axes_m = eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt() * magnification;
    const Eigen::Vector2d major = eigen.eigenvectors().col(1);
    // The page's y axis points down: an angle counter-clockwise in the view is clockwise
    // on the page.
    const double angle_deg = -std::atan2(major.y(), major.x()) * kRadToDeg;
    svg << "<ellipse cx='" << cx << "' cy='" << cy << "' rx='" << axes_m(1) * pixels_per_m
        << "' ry='" << axes_m(0) * pixels_per_m << "' transform='rotate(" << angle_deg << ' ' << cx
        << ' ' << cy << ")' fill='" << m.color << "' fill-opacity='0.2' stroke='" << m.color
        << "'/><circle r='3' fill='" << m.color << "' cx='" << cx << "' cy='" << cy
        << "'/><text x='" << cx + 5 << "' y='" << cy - 5 << "' fill='" << m.color << "'>"
        << Escape(m.label) << "</text>";
  }
  svg << "</svg></figure>\n";
  return svg.str();
}

std::string ResidualHistogram(const std::string& title, const std::string& x_label,
                              const std::string& y_label, const std::string& unit, double range,
                              const std::vector<double>& before, const std::vector<double>& after,
                              bool standard_normal_reference) {
  std::vector<Series> series;
  const std::pair<const char*, const std::vector<double>*> sets[2] = {{"before", &before},
                                                                      {"after", &after}};
  const char* colors[2] = {"#c33", "#36c"};
  for (int k = 0; k < 2; ++k) {
    const ResidualStats stats = Statistics(*sets[k].second, range);
    if (stats.count == 0) continue;
    const std::string label = std::string(sets[k].first) + ": RMS " + Number(stats.rms) + " " +
                              unit + ", " + Percent(stats.beyond_range) + " beyond ±" +
                              Number(range) + " " + unit + " (n = " + std::to_string(stats.count) +
                              ")";
    series.push_back(HistogramSeries(label, colors[k], *sets[k].second, range, stats.count));
  }
  if (series.empty()) return "";
  if (standard_normal_reference) {
    // Share of N(0, 1) in a bin of width w around x: phi(x) w (Eq. R2), in percent.
    Series normal{"standard normal", "#888", {}, {}};
    normal.dashed = true;
    const double width = 2.0 * range / kHistogramBins;
    constexpr int kSamples = 121;
    for (int i = 0; i < kSamples; ++i) {
      const double x = -range + 2.0 * range * i / (kSamples - 1);
      normal.x.push_back(x);
      normal.y.push_back(100.0 * std::exp(-0.5 * x * x) / std::sqrt(2.0 * M_PI) * width);
    }
    series.push_back(normal);
  }
  return LineChart(title, x_label, y_label, series);
}

}  // namespace pipeline
}  // namespace autocal
