#pragma once

// The output directory of an import, written under a temporary name beside it and renamed
// at the end: a failed or killed import leaves at most a hidden ".<name>.importing-<pid>"
// directory, never one that looks like a dataset. Private to src/import.

#include <string>

namespace autocal {
namespace import {

class OutputDirectory {
 public:
  // Refuses an existing non-empty `path` (or a file there) and creates the temporary
  // directory, so that a bad output location fails before the bag is read.
  explicit OutputDirectory(const std::string& path);
  // Removes the temporary directory unless Commit() ran.
  ~OutputDirectory();
  OutputDirectory(const OutputDirectory&) = delete;
  OutputDirectory& operator=(const OutputDirectory&) = delete;

  const std::string& temporary_path() const { return temporary_; }
  // Renames the temporary directory to the output path.
  void Commit();

 private:
  std::string path_;
  std::string temporary_;
  bool committed_ = false;
};

}  // namespace import
}  // namespace autocal
