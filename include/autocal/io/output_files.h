#pragma once

// Writing outputs so that a run that is stopped or fails never leaves a file or directory that
// looks complete.
//
// - A file is written to a temporary name in its own directory, checked (a full disk says
//   "No space left on device" with the path), fsync'ed (WriteFileAtomically) and renamed
//   into place: the path holds either the old file or the whole new one.
// - A result directory (a calibration result, a simulated dataset) is written as a whole into
//   a sibling "<dir>.partial-XXXXXX", synced once (syncfs) and renamed to <dir> by Commit(). A run
//   killed before then leaves only the ".partial-" directory; <dir> is absent or still the previous
//   result.
// - An existing <dir> is replaced (atomically where the file system can exchange two
//   directories, Linux renameat2) only when it is empty or holds nothing but names such a
//   directory holds (the lists below); any other directory is refused, so that a mistyped
//   --output never deletes unrelated files.
//
// Tools call CheckOutputDirectory / CheckOutputFile before the work starts, so that a bad
// output location is reported in seconds, not after the solve.

#include <string>
#include <vector>

namespace autocal {
namespace io {

enum class OutputKind {
  // calibration.yaml, timings.yaml, trajectory.tum, trajectory_smoothed.tum,
  // calibration_per_iteration.csv, calibration_over_time.csv, states.csv, report.html,
  // evaluation.yaml, status.yaml, repeatability.csv, logs/, fleet.csv, fleet.html
  kResult,
  // sensors.yaml, imu.csv, wheel.csv, gnss.csv, lidar.csv, lidar/, groundtruth/
  kDataset,
};

// Throws autocal::Error with one line when `directory` cannot receive an output of `kind`:
// it exists and is not a directory, its parent does not exist or is not a writable
// directory, or it is a directory holding other files than an output of `kind` holds.
void CheckOutputDirectory(const std::string& directory, OutputKind kind);

// Throws autocal::Error with one line when `path` cannot be written: it is a directory, its
// directory does not exist or is not writable, or it exists and is not writable.
void CheckOutputFile(const std::string& path);

// Replaces the file at `path` by `text` atomically (temporary file in the same directory,
// write, fsync, rename). Throws autocal::Error naming the path and the system's reason.
void WriteFileAtomically(const std::string& path, const std::string& text);

// A result's warnings.txt: one warning a line (a line break inside one becomes a space), an
// empty file when there are none; written as WriteFileAtomically writes.
void WriteWarningsFile(const std::string& path, const std::vector<std::string>& warnings);

// A result directory under construction (see the top of this file).
class StagedDirectory {
 public:
  // Checks `directory` (CheckOutputDirectory) and creates the sibling staging directory.
  StagedDirectory(const std::string& directory, OutputKind kind);
  // Removes the staging directory unless Commit() succeeded.
  ~StagedDirectory();
  StagedDirectory(const StagedDirectory&) = delete;
  StagedDirectory& operator=(const StagedDirectory&) = delete;

  // Where the files go until Commit().
  const std::string& staging() const { return staging_; }
  // staging() + "/" + name.
  std::string File(const std::string& name) const;
  // Moves the staging directory to the final name, replacing a replaceable one.
  void Commit();

 private:
  std::string directory_;
  std::string staging_;
  OutputKind kind_;
  bool committed_ = false;
};

}  // namespace io
}  // namespace autocal
