#pragma once

// A fleet's calibrations gathered (docs/fleet.md): N result directories of autocal_calibrate
// (one per vehicle or log, each with its status.yaml) into one table and one HTML overview:
// per vehicle the estimated values and sigma, the vehicles whose value lies far from the
// fleet's, and the runs that failed with their messages.

#include <optional>
#include <string>
#include <vector>

#include "autocal/io/calibration_yaml.h"
#include "autocal/io/run_status.h"

namespace autocal {
namespace pipeline {

struct FleetEntry {
  std::string directory;
  std::optional<io::RunStatus> status;             // absent: no readable status.yaml
  std::optional<io::CalibrationFile> calibration;  // when the run succeeded
  std::string failure;  // why there is no calibration, in words; empty when there is one
  std::string vehicle;  // the status's label, else DirectoryName(directory)
};

// One value of the table, in the calibration file's units (SI) under its column name
// (sensors::ValueColumns: wheel_radius_left_m, p_I_A_x_m); a rotation as roll, pitch and yaw
// in degrees (q_I_L_roll_deg: the LiDAR in the IMU frame; q_I_V_*: the IMU in the vehicle).
struct FleetColumn {
  std::string name;
  std::string direction;   // in words
  bool angle_deg = false;  // a rotation's roll, pitch or yaw: compared on the circle
};

// A vehicle whose value lies more than kFleetOutlierSigmas robust sigmas (1.4826 MAD) of the
// fleet from the fleet's median, and as many of its own sigma: far from the other vehicles
// and farther than its own estimate's error explains. Angles are compared on the circle (a
// roll of 179.75 and one of -178.28 deg lie 3.97 deg apart; the median is the circle's). At 5 a
// vehicle of an honest fleet is flagged in about one of 10^6 values (its own sigma) however the
// vehicles differ.
constexpr double kFleetOutlierSigmas = 5.0;
struct FleetOutlier {
  size_t entry = 0;
  size_t column = 0;
  double value = 0.0, median = 0.0, robust_sigma = 0.0;
  std::string text;  // in words
};

struct FleetReport {
  std::vector<FleetEntry> entries;   // in the order given
  std::vector<FleetColumn> columns;  // every direction a succeeded run reports a sigma for
  // values[e][c] and sigmas[e][c], NaN where entry e has no value for column c.
  std::vector<std::vector<double>> values, sigmas;
  std::vector<FleetOutlier> outliers;
  size_t succeeded = 0;
};

// The name a directory gives the vehicle or log it holds: the last non-empty component of
// its absolute, normalized path ("runs/car_1/" and "runs/car_1/." give "car_1", "." the
// working directory's name); empty only for the root.
std::string DirectoryName(const std::string& directory);

// Reads every directory; a missing or malformed file makes that entry a failure with the
// reason, never an exception. Outliers need at least three succeeded runs.
FleetReport GatherFleet(const std::vector<std::string>& result_directories);

// A text field of fleet.csv and repeatability.csv: in double quotes, a quote inside doubled
// (RFC 4180), so that a name or message with a comma, quote or line break stays one field.
std::string CsvText(const std::string& text);

// fleet.csv: vehicle, directory, exit_status, message (quoted by CsvText), then value and
// sigma per column.
std::string FleetCsv(const FleetReport& report);

// fleet.html: counts, the failures with their messages, the outliers, and the table.
std::string FleetReportHtml(const FleetReport& report);

}  // namespace pipeline
}  // namespace autocal
