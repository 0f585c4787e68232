#include "report_bound.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "autocal/sensors/calibration_blocks.h"
#include "html_page.h"
#include "svg_chart.h"

namespace autocal {
namespace pipeline {

namespace {

double Sigma(const estimation::BlockCovariance& covariance, int row) {
  return std::sqrt(std::max(0.0, covariance.matrix(row, row)));
}

// Sources as the report names them.
std::string SourceName(const std::string& source) {
  if (source == "lidar") return "LiDAR";
  if (source == "imu") return "IMU";
  if (source == "gnss") return "GNSS";
  if (source == "wheel") return "wheels";
  if (source == "planar_rotation") return "planar rotation";
  return source;
}

// The error budget's table (docs/evaluation.md, "Where the error comes from"): per direction
// the linearized error at the truth and each source's share of it, with the share over its
// spread.
std::string BudgetTable(const OfflineCalibrationResult& result) {
  if (!result.error_budget) return "";
  const estimation::ErrorBudget& budget = *result.error_budget;
  const estimation::CalibrationPosterior& posterior = result.posterior;
  std::ostringstream rows;
  for (size_t b = 0; b < posterior.blocks.size(); ++b) {
    const estimation::EstimatedBlock& block = posterior.blocks[b];
    const sensors::CalibrationBlockInfo& info = sensors::CalibrationBlock(block.id);
    for (int i = 0; i < block.size; ++i) {
      const int row = budget.covariance.offsets[b] + i;
      rows << "<tr><td>" << EscapeXml(block.direction_names[static_cast<size_t>(i)]) << " ("
           << info.display_unit << ")</td><td>"
           << Number(budget.share.row(row).sum() * info.display_scale) << "</td>";
      for (Eigen::Index s = 0; s < budget.share.cols(); ++s) {
        const double spread = budget.spread(row, s);
        rows << "<td>" << Number(budget.share(row, s) * info.display_scale) << " ("
             << (spread > 0.0 ? Number(budget.share(row, s) / spread) : "–") << ")</td>";
      }
      rows << "</tr>";
    }
  }
  std::string header = "<tr><th>direction</th><th>error to first order</th>";
  for (const std::string& source : budget.sources) {
    header += "<th>" + EscapeXml(SourceName(source)) + "</th>";
  }
  return "<h3>Where the error comes from</h3><p>From the truth, one Gauss–Newton step of the "
         "final problem lands on the estimate to first order, so the step's opposite is the "
         "error, truth − estimate (the bound table's error, to first order), and it splits by "
         "the data that pull it. Each source's share is followed, "
         "in parentheses, by the share over its spread: the standard deviation of that share "
         "were the source's noise as the model states it. Shares of a few spreads show a "
         "source whose data disagree with its model; the spreads' squares sum to the bound's "
         "variance.</p><table>" +
         header + "</tr>" + rows.str() + "</table>\n";
}

}  // namespace

std::string BoundSection(const OfflineCalibrationResult& result) {
  const estimation::CalibrationPosterior& posterior = result.posterior;
  if (!result.bound || !posterior.covariance.ok) return "";
  const bool with_error = result.error_at_bound.size() == result.bound->matrix.rows();
  std::ostringstream rows;
  for (size_t b = 0; b < posterior.blocks.size(); ++b) {
    const estimation::EstimatedBlock& block = posterior.blocks[b];
    const sensors::CalibrationBlockInfo& info = sensors::CalibrationBlock(block.id);
    for (int i = 0; i < block.size; ++i) {
      const double sigma = Sigma(posterior.covariance, posterior.covariance.offsets[b] + i);
      const double bound = Sigma(*result.bound, result.bound->offsets[b] + i);
      rows << "<tr><td>" << EscapeXml(block.direction_names[static_cast<size_t>(i)]) << " ("
           << info.display_unit << ")</td><td>" << Number(sigma * info.display_scale) << "</td><td>"
           << Number(bound * info.display_scale) << "</td><td>"
           << (bound > 0.0 ? Number(sigma / bound) : "–") << "</td>";
      if (with_error) {
        const double error = result.error_at_bound(result.bound->offsets[b] + i);
        rows << "<td>" << Number(error * info.display_scale) << "</td><td>"
             << (bound > 0.0 ? Number(error / bound) : "–") << "</td>";
      }
      rows << "</tr>";
    }
  }
  const std::string body = rows.str();
  if (body.empty()) return "";
  return "<h2>Against the Cramér–Rao bound</h2><p>The σ of each estimated direction from the "
         "final problem (its information at the estimate, before any direction was held) "
         "against the bound: the same information at the ground truth. An efficient estimate "
         "has a ratio near 1; its errors (truth − estimate) over many logs scatter as the "
         "bound says: error / bound is a standard normal draw, and its RMS over logs is 1.</p>"
         "<table><tr><th>direction</th><th>σ</th><th>bound</th><th>σ / bound</th>" +
         std::string(with_error ? "<th>error</th><th>error / bound</th>" : "") + "</tr>" + body +
         "</table>\n" + BudgetTable(result);
}

}  // namespace pipeline
}  // namespace autocal
