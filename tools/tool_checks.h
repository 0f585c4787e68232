#pragma once

// Checks the tools make before any work starts, so that a wrong --dataset, --output or
// --threads is reported in a second with one line, not after a solve of minutes.

#include <filesystem>
#include <string>
#include <system_error>

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

// --threads=N (N >= 1) replaces the problem file's solver.num_threads; 0 keeps it.
inline void ApplyThreadsFlag(int threads, io::Problem* problem) {
  if (threads < 0 || threads > kMaxThreads) {
    throw Error("--threads must be 0 (the problem file's solver.num_threads) or 1.." +
                std::to_string(kMaxThreads) + ", got " + std::to_string(threads));
  }
  if (threads > 0) problem->solver.num_threads = threads;
}

}  // namespace tools
}  // namespace autocal
