#pragma once

// --help and -h of the tools: the usage message and the tool's own flags, one line each,
// instead of gflags' listing, which puts about a hundred logging and gflags flags first.
// --helpfull still lists every flag (gflags handles it and the other --help* flags).
//
//   gflags::SetUsageMessage("...");
//   if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_x")) return 0;
//   gflags::ParseCommandLineFlags(&argc, &argv, true);

#include <gflags/gflags.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace autocal {
namespace tools {

// True when argv asks for the short help: -h, -help or --help (also "=true"), or
// --helpshort, before a "--" and not as the value of the flag before it.
inline bool AsksForShortHelp(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--") return false;
    if (arg.size() < 2 || arg[0] != '-') continue;
    const std::string name = arg.substr(arg[1] == '-' ? 2 : 1);
    if (name == "h" || name == "help" || name == "help=true" || name == "helpshort") return true;
    // "--flag value" takes the next argument as the value of a flag that is no bool.
    gflags::CommandLineFlagInfo info;
    if (name.find('=') == std::string::npos &&
        gflags::GetCommandLineFlagInfo(name.c_str(), &info) && info.type != "bool") {
      ++i;
    }
  }
  return false;
}

// A flag's default as a user would write it: strings quoted, doubles without the binary
// rounding that gflags prints (0.4, not 0.40000000000000002).
inline std::string ShownDefault(const gflags::CommandLineFlagInfo& flag) {
  if (flag.type == "string") return "\"" + flag.default_value + "\"";
  if (flag.type != "double") return flag.default_value;
  char text[32];
  std::snprintf(text, sizeof(text), "%.12g", std::strtod(flag.default_value.c_str(), nullptr));
  return text;
}

// One line per flag defined in `source_file` (e.g. "autocal_simulate.cc"):
//   --name=TYPE  description (default: value)
inline std::string OwnFlagsText(const std::string& source_file) {
  std::vector<gflags::CommandLineFlagInfo> flags;
  gflags::GetAllFlags(&flags);
  std::string text;
  for (const gflags::CommandLineFlagInfo& flag : flags) {
    const std::string& file = flag.filename;
    const bool own =
        file.size() >= source_file.size() &&
        file.compare(file.size() - source_file.size(), std::string::npos, source_file) == 0;
    if (!own) continue;
    text += "  --" + flag.name + "=" + flag.type + "  " + flag.description;
    text += " (default: " + ShownDefault(flag) + ")\n";
  }
  return text;
}

// Prints the usage message and the flags of tools/<tool>.cc to stdout and returns true when
// argv asks for help (AsksForShortHelp); the caller then exits with status 0.
inline bool ShowShortHelpIfAsked(int argc, char** argv, const std::string& tool) {
  if (!AsksForShortHelp(argc, argv)) return false;
  std::printf("%s\n\nFlags of %s:\n%s\n--helpfull lists every flag, logging (glog) included.\n",
              gflags::ProgramUsage(), tool.c_str(), OwnFlagsText(tool + ".cc").c_str());
  return true;
}

}  // namespace tools
}  // namespace autocal
