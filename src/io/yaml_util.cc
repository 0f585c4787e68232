#include "io/yaml_util.h"

#include <cmath>
#include <cstdio>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "io/text_format.h"

namespace autocal {
namespace io {
namespace internal {
namespace {

// A quaternion read from a file is a rotation only if its norm is 1 up to rounding of the
// printed digits; anything further off is a wrong column or a typo, not a rotation.
constexpr double kMaxQuaternionNormError = 1e-3;
// Below this, |q| - 1 is floating-point noise: leave the coefficients untouched so that a
// written file reads back bit for bit.
constexpr double kNormalizeThreshold = 1e-15;

const char* NodeKind(const YAML::Node& node) {
  switch (node.Type()) {
    case YAML::NodeType::Map:
      return "a map";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Scalar:
      return "a scalar";
    case YAML::NodeType::Null:
      return "nothing (null)";
    case YAML::NodeType::Undefined:
      return "nothing";
  }
  return "an unknown node";
}

SourceLocation Location(const std::string& path, const YAML::Mark& mark) {
  SourceLocation location;
  location.file = path;
  if (!mark.is_null()) {
    location.line = mark.line + 1;
    location.column = mark.column + 1;
  }
  return location;
}

}  // namespace

YamlFile::YamlFile(std::string path) : path_(std::move(path)) {
  const std::string text = ReadFileBytes(path_);
  std::vector<YAML::Node> documents;
  try {
    documents = YAML::LoadAll(text);
  } catch (const YAML::Exception& e) {
    throw ParseError(Location(path_, e.mark), "YAML syntax error: " + e.msg);
  }
  // One document per file: a second (two files joined, a stray '---') would be dropped
  // without a word, and with it whatever it sets.
  for (size_t i = 1; i < documents.size(); ++i) {
    if (documents[i].IsDefined() && !documents[i].IsNull()) {
      Fail(documents[i], "a second YAML document (after '---'): the file must hold one");
    }
  }
  if (!documents.empty()) root_ = documents.front();
  if (!root_.IsDefined() || root_.IsNull()) {
    SourceLocation location;
    location.file = path_;
    location.line = 1;
    location.column = 1;
    throw ParseError(location, "empty YAML document");
  }
}

void YamlFile::Fail(const YAML::Node& node, const std::string& message) const {
  throw ParseError(Location(path_, node.Mark()), message);
}

void YamlFile::ExpectMap(const YAML::Node& node, const std::string& what,
                         std::initializer_list<const char*> allowed) const {
  if (!node.IsMap()) Fail(node, what + ": expected a map, found " + NodeKind(node));
  std::set<std::string> seen;
  for (const auto& entry : node) {
    const YAML::Node& key_node = entry.first;
    if (!key_node.IsScalar()) Fail(key_node, what + ": map keys must be plain names");
    const std::string key = key_node.Scalar();
    bool known = false;
    for (const char* name : allowed) known = known || key == name;
    if (!known) {
      std::string list;
      for (const char* name : allowed) list += (list.empty() ? "" : ", ") + std::string(name);
      Fail(key_node, what + ": unknown key '" + key + "' (expected one of: " + list + ")");
    }
    if (!seen.insert(key).second) Fail(key_node, what + ": key '" + key + "' appears twice");
  }
}

YAML::Node YamlFile::Required(const YAML::Node& map, const std::string& what,
                              const char* key) const {
  const YAML::Node child = map[key];
  if (!child.IsDefined()) Fail(map, what + ": missing required key '" + key + "'");
  return child;
}

double YamlFile::Double(const YAML::Node& node, const std::string& what) const {
  if (!node.IsScalar()) Fail(node, what + ": expected a number, found " + NodeKind(node));
  double value = 0.0;
  std::string why;
  if (!ParseFiniteDouble(node.Scalar(), &value, &why)) Fail(node, what + ": " + why);
  return value;
}

double YamlFile::DoubleInRange(const YAML::Node& node, const std::string& what, double min_value,
                               double max_value, const std::string& unit) const {
  const double value = Double(node, what);
  if (!(value >= min_value && value <= max_value)) {
    Fail(node, what + ": must be within [" + FormatDouble(min_value) + ", " +
                   FormatDouble(max_value) + "] " + unit + ", found " + node.Scalar());
  }
  return value;
}

double YamlFile::Positive(const YAML::Node& node, const std::string& what) const {
  const double value = Double(node, what);
  if (!(value > 0.0)) Fail(node, what + ": must be > 0, found " + node.Scalar());
  return value;
}

int64_t YamlFile::Int(const YAML::Node& node, const std::string& what) const {
  if (!node.IsScalar()) Fail(node, what + ": expected an integer, found " + NodeKind(node));
  int64_t value = 0;
  std::string why;
  if (!ParseInt64(node.Scalar(), &value, &why)) Fail(node, what + ": " + why);
  return value;
}

bool YamlFile::Bool(const YAML::Node& node, const std::string& what) const {
  if (node.IsScalar()) {
    const std::string& text = node.Scalar();
    if (text == "true") return true;
    if (text == "false") return false;
  }
  Fail(node, what + ": expected true or false, found " +
                 (node.IsScalar() ? Quote(node.Scalar()) : std::string(NodeKind(node))));
}

std::string YamlFile::String(const YAML::Node& node, const std::string& what) const {
  if (!node.IsScalar()) Fail(node, what + ": expected a scalar value, found " + NodeKind(node));
  return node.Scalar();
}

Eigen::Vector3d YamlFile::Vector3(const YAML::Node& node, const std::string& what) const {
  if (!node.IsSequence() || node.size() != 3) {
    Fail(node, what + ": expected a list of 3 numbers [x, y, z], found " +
                   (node.IsSequence() ? "a list of " + std::to_string(node.size())
                                      : std::string(NodeKind(node))));
  }
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) v[i] = Double(node[i], what + "[" + std::to_string(i) + "]");
  return v;
}

Eigen::Vector3d YamlFile::NonNegative3(const YAML::Node& node, const std::string& what) const {
  const Eigen::Vector3d v = Vector3(node, what);
  if (v.minCoeff() < 0.0) Fail(node, what + ": a sigma must be >= 0");
  return v;
}

Eigen::Quaterniond YamlFile::QuaternionXyzw(const YAML::Node& node, const std::string& what) const {
  if (!node.IsSequence() || node.size() != 4) {
    Fail(node, what + ": expected a quaternion [qx, qy, qz, qw], found " +
                   (node.IsSequence() ? "a list of " + std::to_string(node.size())
                                      : std::string(NodeKind(node))));
  }
  Eigen::Vector4d xyzw;
  for (int i = 0; i < 4; ++i) xyzw[i] = Double(node[i], what + "[" + std::to_string(i) + "]");
  const double norm = xyzw.norm();
  if (std::abs(norm - 1.0) > kMaxQuaternionNormError) {
    char buffer[64];
    std::snprintf(buffer, sizeof(buffer), "%.6g", norm);
    Fail(node, what + ": quaternion [qx, qy, qz, qw] has norm " + buffer +
                   ", not a rotation (|norm - 1| must be <= 1e-3)");
  }
  if (std::abs(norm - 1.0) > kNormalizeThreshold) xyzw /= norm;
  return Eigen::Quaterniond(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
}

std::vector<bool> YamlFile::Observable(const YAML::Node& node, const std::string& what,
                                       int axes) const {
  if (node.IsScalar()) return {Bool(node, what)};
  if (!node.IsSequence() || static_cast<int>(node.size()) != axes) {
    Fail(node, what + ": expected true, false or a list of " + std::to_string(axes) + " booleans");
  }
  std::vector<bool> flags;
  for (int i = 0; i < axes; ++i)
    flags.push_back(Bool(node[i], what + "[" + std::to_string(i) + "]"));
  return flags;
}

std::string YamlString(const std::string& text) {
  bool plain = !text.empty();
  for (char c : text) {
    const bool safe = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                      c == '_' || c == '.' || c == '-' || c == '+';
    plain = plain && safe;
  }
  // Words YAML would read as booleans or null must be quoted to stay strings.
  static const std::set<std::string> kReserved = {
      "true", "false", "True", "False", "TRUE", "FALSE", "yes", "no", "Yes",
      "No",   "YES",   "NO",   "on",    "off",  "On",    "Off", "ON", "OFF",
      "null", "Null",  "NULL", "y",     "n",    "Y",     "N"};
  if (plain && text[0] != '-' && kReserved.count(text) == 0) return text;
  std::string out = "\"";
  for (char c : text) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buffer[8];
          std::snprintf(buffer, sizeof(buffer), "\\x%02x", static_cast<unsigned char>(c));
          out += buffer;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

}  // namespace internal
}  // namespace io
}  // namespace autocal
