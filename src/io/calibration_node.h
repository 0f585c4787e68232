#pragma once

// Reads the calibration schema from a YAML node, for calibration.yaml files and for the
// nominal_calibration section of sensors.yaml. Private to src/io.

#include <yaml-cpp/yaml.h>

#include <string>

#include "autocal/io/calibration_yaml.h"
#include "io/yaml_util.h"

namespace autocal {
namespace io {
namespace internal {

// `what` prefixes key names in messages ("nominal_calibration").
CalibrationFile ParseCalibrationNode(const YamlFile& file, const YAML::Node& node,
                                     const std::string& what);

}  // namespace internal
}  // namespace io
}  // namespace autocal
