#include "import/output_directory.h"

#include <unistd.h>

#include <filesystem>

#include "autocal/common/error.h"

namespace autocal {
namespace import {

namespace fs = std::filesystem;

OutputDirectory::OutputDirectory(const std::string& path) : path_(path) {
  if (path.empty()) throw Error("no output directory given");
  fs::path output = fs::path(path).lexically_normal();
  if (output.filename().empty()) output = output.parent_path();  // "dir/" -> "dir"
  std::error_code error;
  if (fs::exists(output, error)) {
    if (!fs::is_directory(output, error)) {
      throw Error("output '" + path + "' exists and is not a directory");
    }
    if (!fs::is_empty(output, error)) {
      throw Error("output directory '" + path +
                  "' exists and is not empty: choose a new one (nothing is overwritten)");
    }
  }
  const fs::path parent = output.has_parent_path() ? output.parent_path() : fs::path(".");
  if (!fs::is_directory(parent, error)) {
    throw Error("the output's parent directory '" + parent.string() + "' does not exist");
  }
  path_ = output.string();
  temporary_ =
      (parent / ("." + output.filename().string() + ".importing-" + std::to_string(::getpid())))
          .string();
  fs::remove_all(temporary_, error);
  if (!fs::create_directory(temporary_, error)) {
    throw Error("cannot create '" + temporary_ + "' beside the output: " + error.message());
  }
}

OutputDirectory::~OutputDirectory() {
  if (committed_) return;
  std::error_code error;
  fs::remove_all(temporary_, error);
}

void OutputDirectory::Commit() {
  std::error_code error;
  // An empty output directory may stand in the way; rename() replaces only empty ones.
  if (fs::exists(path_, error)) fs::remove(path_, error);
  fs::rename(temporary_, path_, error);
  if (error) {
    throw Error("cannot rename '" + temporary_ + "' to '" + path_ + "': " + error.message());
  }
  committed_ = true;
}

}  // namespace import
}  // namespace autocal
