#pragma once

// Inline SVG charts for the calibration report (docs/report.md): line charts of data series
// and before/after residual histograms, each a <figure> of fixed size with its axis ranges,
// axis labels and legend; and the text escaping and number formatting the page shares with
// them.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace autocal {
namespace pipeline {

// `text` with the HTML special characters replaced by entities.
std::string Escape(const std::string& text);

// Four significant digits; "–" for a non-finite value, so that no "nan" or "inf" reaches the
// page.
std::string Number(double v);

struct Series {
  std::string label;
  std::string color;
  std::vector<double> x, y;
  bool dots = false;     // points instead of a line
  bool markers = false;  // a line with a dot at each point (few, discrete samples)
  bool dashed = false;   // a reference curve rather than data
};

// A line chart with axis labels and a legend; empty when no series has a finite point.
// With equal_scale a metre east spans as many pixels as a metre north (a track from above).
std::string LineChart(const std::string& title, const std::string& x_label,
                      const std::string& y_label, const std::vector<Series>& series,
                      bool equal_scale = false);

// A sensor in a view of the rig: its position in the view's two axes (m) and the 2x2
// covariance of that position (m^2).
struct RigMark {
  std::string label;
  std::string color;
  double x = 0.0, y = 0.0;
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
};

// One view of the rig at equal scale: each sensor a dot with its label and its 1-sigma
// ellipse drawn `magnification` times larger (the caption says so), so that millimetre
// uncertainties show against a vehicle's metres. Empty without a finite mark.
std::string RigView(const std::string& title, const std::string& x_label,
                    const std::string& y_label, const std::vector<RigMark>& marks,
                    double magnification);

// The before/after histograms of one sensor's residuals, with RMS and the share outside the
// range in the legend; empty when neither set has a finite value.
std::string ResidualHistogram(const std::string& title, const std::string& x_label,
                              const std::string& y_label, const std::string& unit, double range,
                              const std::vector<double>& before, const std::vector<double>& after,
                              bool standard_normal_reference);

}  // namespace pipeline
}  // namespace autocal
