#pragma once

// Reading warnings back in tests: a result's warnings.txt, and the fixed-block warnings of
// Eq. C7 (docs/calibration.md; the window's in docs/sliding_window.md, "Fixed blocks"):
// "<direction> is fixed, but the data would move it by <step> <unit> (sigma <sigma> <unit>, ...".

#include <fstream>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

namespace autocal {
namespace test {

struct FixedDirectionStep {
  double step = 0.0;   // display units (deg, cm, ms, ...)
  double sigma = 0.0;  // the same units
};

// The warnings that name a fixed direction the data would move, each printed.
inline std::vector<std::string> FixedDirectionWarnings(const std::vector<std::string>& warnings) {
  std::vector<std::string> out;
  for (const std::string& w : warnings) {
    if (w.find(" is fixed, but the data would move it by ") == std::string::npos) continue;
    std::cout << w << "\n";
    out.push_back(w);
  }
  return out;
}

// The step and sigma of the warning that names `direction` ("mount pitch (about the vehicle's
// left axis)"); none when no warning names it.
inline std::optional<FixedDirectionStep> StepOfFixedDirection(
    const std::vector<std::string>& warnings, const std::string& direction) {
  const std::string start = direction + " is fixed, but the data would move it by ";
  for (const std::string& w : warnings) {
    if (w.rfind(start, 0) != 0) continue;
    const size_t sigma = w.find("(sigma ", start.size());
    if (sigma == std::string::npos) return std::nullopt;
    return FixedDirectionStep{std::stod(w.substr(start.size())),
                              std::stod(w.substr(sigma + std::string("(sigma ").size()))};
  }
  return std::nullopt;
}

// The lines of a result's warnings.txt (io::WriteWarningsFile).
inline std::vector<std::string> WarningsFileLines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

}  // namespace test
}  // namespace autocal
