// autocal_coverage: does a sensor rig see what a driving scenario needs? The course's
// coverage analysis (§1.3) on a rig file. See docs/coverage.md.

#include <gflags/gflags.h>

#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <system_error>

#include "autocal/common/error.h"
#include "autocal/coverage/coverage.h"
#include "autocal/io/coverage_yaml.h"
#include "autocal/io/output_files.h"
#include "tool_help.h"

DEFINE_string(rig, "", "rig file: the body and each sensor's mounting and field of view");
DEFINE_string(scenario, "urban", "highway, urban (the course's values) or a scenario file");
DEFINE_string(output, "",
              "directory for coverage.md and coverage.svg (created; optional); an existing one "
              "must hold nothing but those");

namespace {

constexpr int kExitShort = 2;

// Throws autocal::Error unless --output can receive coverage.md and coverage.svg: absent, or
// a directory holding nothing but those (a previous coverage output). Any other directory is
// refused, as the other tools refuse one, so that a mistyped --output never mixes the
// report into unrelated files or replaces one of them.
void CheckCoverageOutput(const std::string& directory) {
  namespace fs = std::filesystem;
  std::error_code error;
  if (!fs::exists(directory, error)) return;
  if (!fs::is_directory(directory, error)) {
    throw autocal::Error("--output '" + directory + "': it exists and is not a directory");
  }
  for (const fs::directory_entry& entry : fs::directory_iterator(directory, error)) {
    const std::string name = entry.path().filename().string();
    if (name != "coverage.md" && name != "coverage.svg") {
      throw autocal::Error("--output '" + directory + "': it exists and holds '" + name +
                           "', which is not part of a coverage output; name a new directory or "
                           "remove it");
    }
  }
  if (error) throw autocal::Error("--output '" + directory + "': " + error.message());
}

autocal::coverage::Scenario Scenario() {
  if (FLAGS_scenario == "highway" || FLAGS_scenario == "urban") {
    return autocal::io::ScenarioPreset(FLAGS_scenario);
  }
  return autocal::io::ReadScenarioYaml(FLAGS_scenario);
}

// The scenario's distances, as the course derives them.
std::string Distances(const autocal::coverage::Scenario& s) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(2) << "scenario " << s.name << ": " << s.speed_m_s * 3.6
      << " km/h; emergency stop " << autocal::coverage::EmergencyStopRangeM(s) << " m (aggressive "
      << s.aggressive_deceleration_m_s2 << " m/s^2), following "
      << autocal::coverage::FollowingRangeM(s) << " m, time gap " << s.speed_m_s * s.time_gap_s
      << " m (" << s.time_gap_s << " s)\n";
  return out.str();
}

}  // namespace

int main(int argc, char** argv) {
  gflags::SetUsageMessage(
      "checks a sensor rig against a driving scenario's coverage needs\n"
      "  autocal_coverage --rig=FILE [--scenario=highway|urban|FILE] [--output=DIR]\n"
      "Exit status: 0 every region covered, 2 some region short (named in the table), 1 bad "
      "input.");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_coverage")) return 0;
  gflags::ParseCommandLineFlags(&argc, &argv, true);
  try {
    if (argc > 1) throw autocal::Error(std::string("unexpected argument '") + argv[1] + "'");
    if (FLAGS_rig.empty()) throw autocal::Error("--rig is required");
    if (!FLAGS_output.empty()) CheckCoverageOutput(FLAGS_output);
    const autocal::coverage::Rig rig = autocal::io::ReadRigYaml(FLAGS_rig);
    const autocal::coverage::Scenario scenario = Scenario();
    const auto result = autocal::coverage::AnalyzeCoverage(rig, scenario);
    const std::string table =
        Distances(scenario) + "\n" + autocal::coverage::CoverageTable(rig, result);
    std::cout << table;
    if (!FLAGS_output.empty()) {
      const std::filesystem::path out(FLAGS_output);
      CheckCoverageOutput(FLAGS_output);  // nothing foreign appeared meanwhile
      std::filesystem::create_directories(out);
      autocal::io::WriteFileAtomically((out / "coverage.md").string(), table);
      autocal::io::WriteFileAtomically((out / "coverage.svg").string(),
                                       autocal::coverage::CoverageSvg(rig, result));
    }
    for (const auto& m : result) {
      if (!m.covered) return kExitShort;
    }
  } catch (const std::exception& e) {
    std::cerr << "autocal_coverage: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
