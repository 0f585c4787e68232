#include "multi_log_report.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "autocal/common/format.h"
#include "html_page.h"
#include "svg_chart.h"

namespace autocal {
namespace pipeline {
namespace {

// `decimals` after the point; "–" for a non-finite value, as svg_chart.h's Number.
std::string Fixed(double value, int decimals) {
  return std::isfinite(value) ? FormatFixed(value, decimals) : "–";
}

// Decimals that show a value of this sigma to about two significant digits of the sigma.
int DecimalsFor(double sigma) {
  if (!(sigma > 0.0) || !std::isfinite(sigma)) return 3;
  return std::max(0, std::min(6, 1 - static_cast<int>(std::floor(std::log10(sigma)))));
}

std::string RepeatabilitySection(const MultiLogCalibrationResult& result) {
  std::ostringstream html;
  html << "<h2>Repeatability</h2><p>Each log's own estimate (sigma before any direction was "
          "held) and the shared one. A block whose chi-square test of one true value gives p "
          "below the threshold is flagged (docs/calibration.md, Eq. M3). Rotations are shown as "
          "the rotation vector from the shared rotation.</p><table><tr><th>block</th>"
          "<th>direction</th><th>unit</th>";
  for (const LogCalibration& log : result.logs) html << "<th>" << EscapeXml(log.name) << "</th>";
  html << "<th>shared</th><th>chi-square / dof</th><th>p</th><th></th></tr>\n";
  for (const RepeatabilityRow& row : RepeatabilityRows(result)) {
    const int decimals = DecimalsFor(row.shared.sigma);
    html << "<tr><td>" << EscapeXml(row.key) << "</td><td>" << EscapeXml(row.direction)
         << "</td><td>" << EscapeXml(row.unit) << "</td>";
    for (const LogCalibration& log : result.logs) {
      html << "<td>";
      for (const RepeatabilityEntry& e : row.logs) {
        if (e.log == log.name) {
          html << Fixed(e.value, decimals) << " ± " << Fixed(e.sigma, decimals);
        }
      }
      html << "</td>";
    }
    const estimation::BlockAgreement& a = row.block->agreement;
    html << "<td>" << Fixed(row.shared.value, decimals) << " ± "
         << Fixed(row.shared.sigma, decimals) << "</td><td>" << Fixed(a.chi_square, 1) << " / "
         << a.degrees_of_freedom << "</td><td>" << Number(a.p_value) << "</td><td"
         << (row.block->agree ? ">agree" : " class='warn'>differ") << "</td></tr>\n";
  }
  html << "</table>\n";
  return html.str();
}

}  // namespace

std::string MultiLogReportHtml(const MultiLogCalibrationResult& result) {
  std::ostringstream html;
  html << HtmlPageStart("autocal calibration of several logs");
  html << "<h2>Shared calibration</h2><pre>"
       << EscapeXml(FormatCalibrationValues(result.calibration)) << "</pre>\n";
  html << RepeatabilitySection(result);
  html << HtmlWarnings("Findings and warnings", result.warnings);
  html << "<h2>Logs</h2><ul>";
  for (const LogCalibration& log : result.logs) {
    html << "<li>" << EscapeXml(log.name) << " (" << EscapeXml(log.dataset_directory)
         << "): " << log.at_shared.trajectory.size()
         << " keyframes at the shared calibration; <a href='logs/"
         << EscapeXml(PercentEncoded(log.name)) << "/own/report.html'>its own calibration</a></li>";
  }
  html << "</ul>\n" << HtmlPageEnd();
  return html.str();
}

}  // namespace pipeline
}  // namespace autocal
