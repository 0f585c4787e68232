#include "autocal/io/run_status.h"

#include <sstream>

#include "autocal/io/output_files.h"
#include "io/yaml_util.h"

namespace autocal {
namespace io {

using internal::YamlFile;

RunStatus ReadRunStatus(const std::string& path) {
  const YamlFile f(path);
  const YAML::Node& root = f.root();
  f.ExpectMap(root, "status.yaml",
              {"format", "tool", "vehicle", "datasets", "exit_status", "message", "seconds"});
  const std::string format = f.String(f.Required(root, "status.yaml", "format"), "format");
  if (format != "autocal_status_1") {
    f.Fail(root["format"], "format: expected autocal_status_1, got '" + format + "'");
  }
  RunStatus status;
  status.tool = f.String(f.Required(root, "status.yaml", "tool"), "tool");
  status.vehicle = f.String(f.Required(root, "status.yaml", "vehicle"), "vehicle");
  const YAML::Node datasets = f.Required(root, "status.yaml", "datasets");
  if (!datasets.IsSequence()) f.Fail(datasets, "datasets: expected a list of directories");
  for (const YAML::Node& d : datasets) status.datasets.push_back(f.String(d, "datasets"));
  const int64_t exit_status = f.Int(f.Required(root, "status.yaml", "exit_status"), "exit_status");
  if (exit_status < 0 || exit_status > 255) {
    f.Fail(root["exit_status"], "exit_status: expected 0 ... 255");
  }
  status.exit_status = static_cast<int>(exit_status);
  status.message = f.String(f.Required(root, "status.yaml", "message"), "message");
  status.seconds =
      f.DoubleInRange(f.Required(root, "status.yaml", "seconds"), "seconds", 0.0, 1e9, "s");
  return status;
}

void WriteRunStatus(const std::string& path, const RunStatus& status) {
  using internal::YamlString;
  std::ostringstream out;
  out << "format: autocal_status_1\n"
      << "tool: " << YamlString(status.tool) << "\n"
      << "vehicle: " << YamlString(status.vehicle) << "\n"
      << "datasets:" << (status.datasets.empty() ? " []" : "") << "\n";
  for (const std::string& dataset : status.datasets) out << "  - " << YamlString(dataset) << "\n";
  out << "exit_status: " << status.exit_status << "\n"
      << "message: " << YamlString(status.message) << "\n"
      << "seconds: " << status.seconds << "\n";
  WriteFileAtomically(path, out.str());
}

}  // namespace io
}  // namespace autocal
