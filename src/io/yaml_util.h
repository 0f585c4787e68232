#pragma once

// Strict YAML access for the io readers: every value is checked for type and range, and
// every problem becomes a ParseError with the file and the node's line and column. yaml-cpp
// stays private to the library (it is not part of any public header). Private to src/io.

#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

namespace autocal {
namespace io {
namespace internal {

// A loaded YAML document and the path it came from.
class YamlFile {
 public:
  // Throws autocal::Error when the file cannot be read, ParseError on a syntax error or
  // an empty document.
  explicit YamlFile(std::string path);

  const std::string& path() const { return path_; }
  const YAML::Node& root() const { return root_; }

  [[noreturn]] void Fail(const YAML::Node& node, const std::string& message) const;

  // Checks that `node` is a map whose keys are all in `allowed` (no duplicates); `what`
  // names the section in messages ("T_I_L", "sensors.yaml").
  void ExpectMap(const YAML::Node& node, const std::string& what,
                 std::initializer_list<const char*> allowed) const;
  // The child `key` of a map that ExpectMap has checked, or a ParseError when absent.
  YAML::Node Required(const YAML::Node& map, const std::string& what, const char* key) const;

  double Double(const YAML::Node& node, const std::string& what) const;
  // A number that must be > 0.
  double Positive(const YAML::Node& node, const std::string& what) const;
  // A number within [min_value, max_value] (`unit` follows the bounds in the message): beyond
  // them a setting is a typo or a unit slip, and extreme magnitudes (1e-300, 1e300) overflow
  // what is built from them (a voxel index, an information matrix).
  double DoubleInRange(const YAML::Node& node, const std::string& what, double min_value,
                       double max_value, const std::string& unit) const;
  int64_t Int(const YAML::Node& node, const std::string& what) const;
  bool Bool(const YAML::Node& node, const std::string& what) const;
  std::string String(const YAML::Node& node, const std::string& what) const;
  Eigen::Vector3d Vector3(const YAML::Node& node, const std::string& what) const;
  // A non-negative 3-vector (sigmas).
  Eigen::Vector3d NonNegative3(const YAML::Node& node, const std::string& what) const;
  // [x, y, z, w]; normalized, rejected when the norm is off 1 by more than 1e-3.
  Eigen::Quaterniond QuaternionXyzw(const YAML::Node& node, const std::string& what) const;
  // true|false, or a list of exactly `axes` booleans.
  std::vector<bool> Observable(const YAML::Node& node, const std::string& what, int axes) const;

 private:
  std::string path_;
  YAML::Node root_;
};

// Text for a string value that reads back unchanged: plain when safe, double-quoted and
// escaped otherwise.
std::string YamlString(const std::string& text);

}  // namespace internal
}  // namespace io
}  // namespace autocal
