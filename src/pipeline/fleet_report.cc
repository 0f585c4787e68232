#include "autocal/pipeline/fleet_report.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <sstream>
#include <system_error>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/io/calibration_block_fields.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/sensors/calibration_blocks.h"
#include "common/order_statistics.h"
#include "html_page.h"
#include "mount_angles.h"

namespace autocal {
namespace pipeline {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

FleetEntry ReadEntry(const std::string& directory) {
  FleetEntry entry;
  entry.directory = directory;
  entry.vehicle = DirectoryName(directory);
  const std::string status_path = directory + "/status.yaml";
  if (!std::filesystem::exists(status_path)) {
    entry.failure = "no status.yaml: the run did not finish (stopped, out of time or memory?)";
    return entry;
  }
  try {
    entry.status = io::ReadRunStatus(status_path);
    if (!entry.status->vehicle.empty()) entry.vehicle = entry.status->vehicle;
    if (entry.status->exit_status != 0) {
      entry.failure = entry.status->message.empty()
                          ? "exit status " + std::to_string(entry.status->exit_status)
                          : entry.status->message;
      return entry;
    }
    entry.calibration = io::ReadCalibrationYaml(directory + "/calibration.yaml");
  } catch (const Error& e) {
    entry.failure = e.what();
  }
  return entry;
}

// One block's values and sigmas in the file's units (SI; a rotation as roll, pitch, yaw in
// degrees with those angles' own sigma), with their column names, or nothing when the file
// gives the block no sigma (not estimated).
struct BlockValues {
  std::vector<double> values, sigmas;
  std::vector<std::string> names, directions;
  bool angles_deg = false;  // roll, pitch and yaw of a rotation
};
std::optional<BlockValues> ValuesOf(const sensors::CalibrationBlockInfo& info,
                                    const io::CalibrationFile& file) {
  const std::optional<Eigen::VectorXd> sigma = io::UncertaintyIn(file.uncertainty, info.id).sigma;
  if (!sigma) return std::nullopt;
  BlockValues out;
  const double* v = info.const_values(file.value);
  if (info.manifold == sensors::BlockManifold::kRightQuaternion) {
    // The angles' own sigma (mount_angles.h), not the axes' beside them.
    const Eigen::Quaterniond mount = DisplayedMount(info, file.value);
    const Eigen::Vector3d rpy = DisplayRollPitchYawDeg(mount, 6);
    const Eigen::Vector3d angle_sigma =
        DisplayedAngleUncertainty(mount, info.id == sensors::CalibrationBlockId::kVehicleRotation,
                                  *sigma, {})
            .sigma_deg;
    out.sigmas = {angle_sigma.x(), angle_sigma.y(), angle_sigma.z()};
    for (const char* angle : {"roll", "pitch", "yaw"}) {
      out.names.push_back(std::string(info.key) + "_" + angle + "_deg");
      out.directions.push_back(angle);
    }
    out.values = {rpy.x(), rpy.y(), rpy.z()};
    out.angles_deg = true;
  } else {
    out.names = sensors::ValueColumns(info);
    out.directions.assign(info.direction_names.begin(),
                          info.direction_names.begin() + info.tangent_size);
    out.values.assign(v, v + info.tangent_size);
    out.sigmas.assign(sigma->data(), sigma->data() + info.tangent_size);
  }
  return out;
}

// One column per direction of every block a run reports a sigma for; NaN where a run has none.
void Tabulate(FleetReport* report) {
  report->values.assign(report->entries.size(), {});
  report->sigmas.assign(report->entries.size(), {});
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    std::vector<std::optional<BlockValues>> per_run;
    const BlockValues* named = nullptr;
    for (const FleetEntry& e : report->entries) {
      per_run.push_back(e.calibration ? ValuesOf(info, *e.calibration) : std::nullopt);
    }
    for (const std::optional<BlockValues>& v : per_run) {
      if (v && named == nullptr) named = &*v;
    }
    if (named == nullptr) continue;
    for (int k = 0; k < info.tangent_size; ++k) {
      report->columns.push_back({named->names[k], named->directions[k], named->angles_deg});
    }
    for (size_t e = 0; e < per_run.size(); ++e) {
      for (int k = 0; k < info.tangent_size; ++k) {
        report->values[e].push_back(per_run[e] ? per_run[e]->values[k] : kNaN);
        report->sigmas[e].push_back(per_run[e] ? per_run[e]->sigmas[k] : kNaN);
      }
    }
  }
}

// `degrees` wrapped into (-180, 180].
double WrapDeg(double degrees) {
  const double wrapped = std::remainder(degrees, 360.0);
  return wrapped <= -180.0 ? wrapped + 360.0 : wrapped;
}

// The signed difference value - centre; for an angle the shorter way round the circle.
double Deviation(double value, double centre, bool angle_deg) {
  return angle_deg ? WrapDeg(value - centre) : value - centre;
}

// The median of a column. An angle's is taken on the circle: the median of the differences
// from a reference, wrapped into (-180, 180], added to it; first about the first value, then
// again about that median, so that a reference far from the others does not matter. A roll of
// 179.75 and one of -178.28 then lie 3.97 degrees apart, not 358.
double Centre(const std::vector<double>& column, bool angle_deg) {
  if (!angle_deg) return internal::Median(column);
  double centre = column.front();
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<double> differences;
    for (const double v : column) differences.push_back(WrapDeg(v - centre));
    centre = WrapDeg(centre + internal::Median(differences));
  }
  return centre;
}

void FindOutliers(FleetReport* report) {
  for (size_t c = 0; c < report->columns.size(); ++c) {
    const FleetColumn& col = report->columns[c];
    std::vector<double> column;
    for (const std::vector<double>& row : report->values) {
      if (std::isfinite(row[c])) column.push_back(row[c]);
    }
    if (column.size() < 3) continue;
    const double median = Centre(column, col.angle_deg);
    std::vector<double> deviations;
    for (const double v : column) deviations.push_back(Deviation(v, median, col.angle_deg));
    const double robust_sigma = internal::MadSigma(deviations);
    for (size_t e = 0; e < report->entries.size(); ++e) {
      const double value = report->values[e][c], sigma = report->sigmas[e][c];
      if (!std::isfinite(value)) continue;
      const double deviation = std::abs(Deviation(value, median, col.angle_deg));
      if (deviation <= kFleetOutlierSigmas * std::max(robust_sigma, sigma)) {
        continue;
      }
      std::ostringstream text;
      text << report->entries[e].vehicle << ": " << col.direction << " " << std::setprecision(7)
           << value << " (" << col.name << "), the fleet's median " << median << " (robust sigma "
           << std::setprecision(3) << robust_sigma << "): " << FormatFixed(deviation / sigma, 1)
           << " of its own sigma off";
      report->outliers.push_back({e, c, value, median, robust_sigma, text.str()});
    }
  }
}

std::string Cell(double value) {
  if (!std::isfinite(value)) return "";
  std::ostringstream out;
  out << std::setprecision(8) << value;
  return out.str();
}

}  // namespace

std::string DirectoryName(const std::string& directory) {
  std::error_code error;
  std::filesystem::path path = std::filesystem::absolute(directory, error);
  if (error) path = directory;
  path = path.lexically_normal();
  if (!path.has_filename()) path = path.parent_path();  // "runs/car_1/" ends in an empty one
  return path.filename().string();
}

FleetReport GatherFleet(const std::vector<std::string>& result_directories) {
  FleetReport report;
  for (const std::string& directory : result_directories) {
    report.entries.push_back(ReadEntry(directory));
    if (report.entries.back().calibration) ++report.succeeded;
  }
  Tabulate(&report);
  FindOutliers(&report);
  return report;
}

std::string CsvText(const std::string& field) {
  std::string text = field;
  for (size_t i = 0; (i = text.find('"', i)) != std::string::npos; i += 2) text.insert(i, "\"");
  return '"' + text + '"';
}

std::string FleetCsv(const FleetReport& report) {
  std::ostringstream csv;
  csv << "vehicle,directory,exit_status,message";
  for (const FleetColumn& c : report.columns) csv << ',' << c.name << ',' << c.name << "_sigma";
  csv << '\n';
  for (size_t e = 0; e < report.entries.size(); ++e) {
    const FleetEntry& entry = report.entries[e];
    csv << CsvText(entry.vehicle) << ',' << CsvText(entry.directory) << ','
        << (entry.status ? std::to_string(entry.status->exit_status) : "") << ','
        << CsvText(entry.failure);
    for (size_t c = 0; c < report.columns.size(); ++c) {
      csv << ',' << Cell(report.values[e][c]) << ',' << Cell(report.sigmas[e][c]);
    }
    csv << '\n';
  }
  return csv.str();
}

std::string FleetReportHtml(const FleetReport& report) {
  std::ostringstream html;
  html << HtmlPageStart("autocal fleet report");
  html << "<p>" << report.entries.size() << " runs: " << report.succeeded << " calibrated, "
       << report.entries.size() - report.succeeded << " failed.</p>\n";
  std::vector<std::string> failures, outliers;
  for (const FleetEntry& e : report.entries) {
    if (!e.calibration) failures.push_back(e.vehicle + " (" + e.directory + "): " + e.failure);
  }
  for (const FleetOutlier& o : report.outliers) outliers.push_back(o.text);
  html << HtmlWarnings("Failures", failures) << HtmlWarnings("Outliers", outliers);
  html << "<h2>Values</h2><table><tr><th>vehicle</th>";
  for (const FleetColumn& c : report.columns) {
    html << "<th>" << EscapeXml(c.name) << "</th>";
  }
  html << "</tr>\n";
  for (size_t e = 0; e < report.entries.size(); ++e) {
    if (!report.entries[e].calibration) continue;
    html << "<tr><td>" << EscapeXml(report.entries[e].vehicle) << "</td>";
    for (size_t c = 0; c < report.columns.size(); ++c) {
      bool outlier = false;
      for (const FleetOutlier& o : report.outliers)
        outlier = outlier || (o.entry == e && o.column == c);
      html << "<td" << (outlier ? " class='warn'" : "") << ">" << Cell(report.values[e][c]);
      if (std::isfinite(report.sigmas[e][c])) html << " ± " << Cell(report.sigmas[e][c]);
      html << "</td>";
    }
    html << "</tr>\n";
  }
  html << "</table>\n" << HtmlPageEnd();
  return html.str();
}

}  // namespace pipeline
}  // namespace autocal
