#pragma once

// Checks the tools make before any work starts, so that a wrong --dataset, --output or
// --threads is reported in a second with one line, not after a solve of minutes.

#include <fnmatch.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/io/problem_yaml.h"

namespace autocal {
namespace tools {

// The largest thread count a problem file accepts (problems/README.md, solver.num_threads).
constexpr int kMaxThreads = 1024;

// Throws autocal::Error when `directory` is no dataset (datasets/README.md): missing, not a
// directory, empty, or without imu.csv (the one file every dataset has).
inline void CheckDatasetDirectory(const std::string& directory) {
  namespace fs = std::filesystem;
  std::error_code error;
  if (!fs::exists(directory, error)) {
    throw Error("--dataset: '" + directory + "' does not exist");
  }
  if (!fs::is_directory(directory, error)) {
    throw Error("--dataset: '" + directory +
                "' is not a directory (a dataset is a directory, "
                "datasets/README.md)");
  }
  if (fs::is_empty(directory, error)) {
    throw Error("--dataset: '" + directory + "' is an empty directory, not a dataset");
  }
  if (!fs::is_regular_file(fs::path(directory) / "imu.csv", error)) {
    throw Error("--dataset: '" + directory +
                "' is not a dataset: it has no imu.csv "
                "(datasets/README.md)");
  }
}

// `path` made absolute with its symbolic links resolved as far as it exists, without a
// trailing separator: two names of one file or directory compare equal.
inline std::filesystem::path ResolvedPath(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code error;
  fs::path resolved = fs::weakly_canonical(fs::absolute(path, error), error);
  if (error) resolved = fs::absolute(path, error).lexically_normal();
  if (!resolved.has_filename() && resolved.has_relative_path()) resolved = resolved.parent_path();
  return resolved;
}

// True when `inner` is `outer` or lies below it (both resolved by ResolvedPath).
inline bool IsWithin(const std::filesystem::path& inner, const std::filesystem::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i) {
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

// Throws autocal::Error when the output directory `output` (flag `flag`) is, holds or lies
// inside one of the directories `inputs` the run reads: writing it would replace or delete
// that input, or put the output among it. Checked before anything is written.
inline void CheckOutputApartFromInputs(const std::string& output, const std::string& flag,
                                       const std::vector<std::string>& inputs) {
  const std::filesystem::path out = ResolvedPath(output);
  for (const std::string& input : inputs) {
    const std::filesystem::path in = ResolvedPath(input);
    const bool holds = IsWithin(in, out), inside = IsWithin(out, in);
    if (!holds && !inside) continue;
    throw Error(flag + ": '" + output + "' " +
                (holds && inside ? "is"
                 : holds         ? "holds"
                                 : "lies inside") +
                " the input '" + input + "'; name a directory apart from the inputs");
  }
}

// Throws autocal::Error when the output file `output` (flag `flag`) is one of the files
// `inputs` names (flag, path): the run would overwrite what it reads. Two names of one file
// (a symbolic or hard link) count as one.
inline void CheckOutputFileIsNoInput(
    const std::string& output, const std::string& flag,
    const std::vector<std::pair<std::string, std::string>>& inputs) {
  namespace fs = std::filesystem;
  const fs::path out = ResolvedPath(output);
  for (const auto& [input_flag, input] : inputs) {
    if (input.empty()) continue;
    std::error_code error;
    if (out == ResolvedPath(input) || fs::equivalent(output, input, error)) {
      throw Error(flag + ": '" + output + "' is the file " + input_flag + " reads ('" + input +
                  "'); name another file");
    }
  }
}

// Throws autocal::Error when --threads is out of range.
inline void CheckThreadsFlag(int threads) {
  if (threads < 0 || threads > kMaxThreads) {
    throw Error("--threads must be 0 (the problem file's solver.num_threads) or 1.." +
                std::to_string(kMaxThreads) + ", got " + std::to_string(threads));
  }
}

// The most stretches --scatter_stretches takes. A sensor with fewer rows (residual blocks)
// than stretches is not tested at all (estimation::ComputeStretchScatter), so a count beyond
// a log's rows would turn the test off without a word; at 1000 a sensor is tested from 1000
// rows on (100 s of 10 Hz fixes).
constexpr int kMaxScatterStretches = 1000;

// Throws autocal::Error unless --scatter_stretches is 0 (no test) or within
// least..kMaxScatterStretches.
inline void CheckScatterStretchesFlag(int stretches, int least) {
  if (stretches != 0 && (stretches < least || stretches > kMaxScatterStretches)) {
    throw Error("--scatter_stretches must be 0 (no test) or " + std::to_string(least) + ".." +
                std::to_string(kMaxScatterStretches) + ", got " + std::to_string(stretches));
  }
}

// --threads=N (N >= 1) replaces the problem file's solver.num_threads; 0 keeps it.
inline void ApplyThreadsFlag(int threads, io::Problem* problem) {
  CheckThreadsFlag(threads);
  if (threads > 0) problem->solver.num_threads = threads;
}

namespace internal {

// The flags of the flagfile `path` appended to *arguments as gflags reads them: one flag a
// line (leading blanks and trailing blanks dropped), blank lines and # comments skipped, a
// line not starting with '-' naming the programs (globs) the flags after it are for, and a
// nested --flagfile followed (at most `depth` deep). An unreadable file adds nothing: gflags
// reports it.
inline void AppendFlagfile(const std::string& path, const std::string& program, int depth,
                           std::vector<std::string>* arguments) {
  std::ifstream in(path);
  if (!in || depth <= 0) return;
  const std::string short_name = std::filesystem::path(program).filename().string();
  bool relevant = true;
  std::string line;
  while (std::getline(in, line)) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    line = line.substr(first, line.find_last_not_of(" \t\r") - first + 1);
    if (line[0] != '-') {  // the programs the following flags are for
      relevant = false;
      std::istringstream globs(line);
      for (std::string glob; globs >> glob;) {
        relevant = relevant || fnmatch(glob.c_str(), program.c_str(), 0) == 0 ||
                   fnmatch(glob.c_str(), short_name.c_str(), 0) == 0;
      }
      continue;
    }
    if (!relevant) continue;
    const size_t name = line.find_first_not_of('-');
    if (name != std::string::npos && line.compare(name, 9, "flagfile=") == 0) {
      AppendFlagfile(line.substr(name + 9), program, depth - 1, arguments);
    } else {
      arguments->push_back(line);
    }
  }
}

}  // namespace internal

// The command line with every --flagfile=FILE (or --flagfile FILE) replaced by the flags in
// FILE, in the order gflags applies them; the program name first.
inline std::vector<std::string> ArgumentsWithFlagfiles(int argc, char** argv) {
  constexpr int kMaxFlagfileDepth = 16;
  const std::string program = argc > 0 ? argv[0] : "";
  std::vector<std::string> arguments = {program};
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const size_t name = arg.find_first_not_of('-');
    if (name == 0 || name > 2 || name == std::string::npos) {
      arguments.push_back(arg);
    } else if (arg.compare(name, std::string::npos, "flagfile") == 0 && i + 1 < argc) {
      internal::AppendFlagfile(argv[++i], program, kMaxFlagfileDepth, &arguments);
    } else if (arg.compare(name, 9, "flagfile=") == 0) {
      internal::AppendFlagfile(arg.substr(name + 9), program, kMaxFlagfileDepth, &arguments);
    } else {
      arguments.push_back(arg);
    }
  }
  return arguments;
}

// Every value of a flag given more than once (--name=V, -name=V, --name V) in `arguments`
// (ArgumentsWithFlagfiles), in order; gflags keeps only the last.
inline std::vector<std::string> RepeatedFlagValues(const std::vector<std::string>& arguments,
                                                   const std::string& name) {
  std::vector<std::string> values;
  for (size_t i = 1; i < arguments.size(); ++i) {
    const std::string& arg = arguments[i];
    for (const std::string& prefix : {"--" + name, "-" + name}) {
      if (arg.rfind(prefix + "=", 0) == 0) {
        values.push_back(arg.substr(prefix.size() + 1));
      } else if (arg == prefix && i + 1 < arguments.size()) {
        values.push_back(arguments[++i]);
      }
    }
  }
  return values;
}

// The lines of a list file (one entry per line; blank lines and lines starting with # are
// skipped, surrounding blanks dropped). Throws autocal::Error when it cannot be read or is
// empty.
inline std::vector<std::string> ReadListFile(const std::string& path, const std::string& flag) {
  std::ifstream in(path);
  if (!in) throw Error(flag + ": cannot read '" + path + "'");
  std::vector<std::string> entries;
  std::string line;
  while (std::getline(in, line)) {
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    entries.push_back(line.substr(first, line.find_last_not_of(" \t\r") - first + 1));
  }
  if (entries.empty()) throw Error(flag + ": '" + path + "' lists no entry");
  return entries;
}

}  // namespace tools
}  // namespace autocal
