#include "autocal/io/output_files.h"

#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <set>
#include <system_error>

#include "autocal/common/error.h"
#include "io/text_format.h"

namespace autocal {
namespace io {
namespace {

namespace fs = std::filesystem;

// The names an output directory of `kind` holds; only such a directory is replaced.
const std::set<std::string>& ReplaceableNames(OutputKind kind) {
  static const std::set<std::string> kResult = {"calibration.yaml",
                                                "timings.yaml",
                                                "trajectory.tum",
                                                "trajectory_smoothed.tum",
                                                "calibration_per_iteration.csv",
                                                "calibration_over_time.csv",
                                                "states.csv",
                                                "report.html",
                                                "evaluation.yaml",
                                                "status.yaml",
                                                "warnings.txt",
                                                "repeatability.csv",
                                                "logs",
                                                "fleet.csv",
                                                "fleet.html"};
  static const std::set<std::string> kDataset = {"sensors.yaml",    "imu.csv",      "wheel.csv",
                                                 "wheel_speed.csv", "odometry.csv", "gnss.csv",
                                                 "lidar.csv",       "lidar",        "groundtruth"};
  return kind == OutputKind::kResult ? kResult : kDataset;
}

const char* KindName(OutputKind kind) {
  return kind == OutputKind::kResult ? "an autocal result" : "an autocal dataset";
}

// `text` as an absolute path without a trailing separator, so that its parent is the
// directory that receives the rename.
fs::path Normalized(const std::string& text) {
  if (text.empty()) throw Error("the output path is empty");
  std::error_code error;
  fs::path path = fs::absolute(fs::path(text), error).lexically_normal();
  if (error) throw Error("cannot resolve the output path '" + text + "': " + error.message());
  if (!path.has_filename()) path = path.parent_path();
  if (!path.has_filename() || path.filename() == "..") {
    throw Error("'" + text + "' cannot be an output: name a directory below it");
  }
  return path;
}

std::string SystemReason() { return std::strerror(errno); }

// The parent of `path` must be an existing directory this process may create files in.
void CheckParent(const fs::path& path, const std::string& shown) {
  const fs::path parent = path.parent_path();
  std::error_code error;
  if (!fs::is_directory(parent, error)) {
    throw Error("cannot write '" + shown + "': the directory '" + parent.string() +
                "' does not exist");
  }
  if (access(parent.c_str(), W_OK | X_OK) != 0) {
    throw Error("cannot write '" + shown + "': cannot create files in '" + parent.string() +
                "': " + SystemReason());
  }
}

void FsyncPath(const std::string& path) {
  const int fd = open(path.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;  // best effort: the rename itself is what makes the result whole
  fsync(fd);
  close(fd);
}

// A name beside `path` that no other writer uses: "<path>.tmp-<pid>-<n>".
std::string TemporaryName(const std::string& path) {
  static std::atomic<unsigned long> counter{0};
  return path + ".tmp-" + std::to_string(static_cast<long>(getpid())) + "-" +
         std::to_string(counter++);
}

// Swaps two directories in one step where the system can (Linux renameat2); false where it
// cannot (errno tells why).
bool ExchangeDirectories(const std::string& a, const std::string& b) {
#ifdef RENAME_EXCHANGE
  return renameat2(AT_FDCWD, a.c_str(), AT_FDCWD, b.c_str(), RENAME_EXCHANGE) == 0;
#else
  errno = ENOSYS;
  return false;
#endif
}

}  // namespace

void CheckOutputDirectory(const std::string& directory, OutputKind kind) {
  const fs::path path = Normalized(directory);
  std::error_code error;
  const fs::file_status status = fs::status(path, error);
  if (fs::exists(status) && !fs::is_directory(status)) {
    throw Error("cannot write '" + directory + "': it exists and is not a directory");
  }
  CheckParent(path, directory);
  if (!fs::exists(status)) return;
  if (access(path.c_str(), W_OK | X_OK) != 0) {
    throw Error("cannot write '" + directory + "': " + SystemReason());
  }
  const std::set<std::string>& names = ReplaceableNames(kind);
  for (const fs::directory_entry& entry : fs::directory_iterator(path, error)) {
    const std::string name = entry.path().filename().string();
    if (!names.count(name)) {
      throw Error("cannot write '" + directory + "': it exists and holds '" + name +
                  "', which is not part of " + KindName(kind) +
                  "; name a new directory or remove it");
    }
  }
  if (error) throw Error("cannot list '" + directory + "': " + error.message());
}

void CheckOutputFile(const std::string& path) {
  const fs::path normalized = Normalized(path);
  std::error_code error;
  if (fs::is_directory(normalized, error)) {
    throw Error("cannot write '" + path + "': it is a directory");
  }
  CheckParent(normalized, path);
  if (fs::exists(normalized, error) && access(normalized.c_str(), W_OK) != 0) {
    throw Error("cannot write '" + path + "': " + SystemReason());
  }
}

namespace internal {

void WriteFileReplacing(const std::string& path, const std::string& text, bool sync) {
  std::error_code error;
  if (fs::is_directory(path, error)) throw Error("cannot write '" + path + "': it is a directory");
  std::string temporary;
  int fd = -1;
  for (int attempt = 0; attempt < 100 && fd < 0; ++attempt) {
    temporary = TemporaryName(path);
    fd = open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0 && errno != EEXIST) break;
  }
  if (fd < 0) throw Error("cannot write '" + path + "': " + SystemReason());
  try {
    internal::WriteAllToDescriptor(fd, text, path);
    // fsync on a file system that cannot (EINVAL) is no failure of the data.
    if (sync && fsync(fd) != 0 && errno != EINVAL && errno != EROFS) {
      throw Error("cannot write '" + path + "': " + SystemReason());
    }
    const int closed = close(fd);
    fd = -1;
    if (closed != 0) throw Error("cannot write '" + path + "': " + SystemReason());
    if (rename(temporary.c_str(), path.c_str()) != 0) {
      throw Error("cannot write '" + path + "': " + SystemReason());
    }
  } catch (...) {
    if (fd >= 0) close(fd);
    unlink(temporary.c_str());
    throw;
  }
}

}  // namespace internal

void WriteFileAtomically(const std::string& path, const std::string& text) {
  internal::WriteFileReplacing(path, text, true);
}

void WriteWarningsFile(const std::string& path, const std::vector<std::string>& warnings) {
  std::string text;
  for (std::string line : warnings) {
    std::replace(line.begin(), line.end(), '\n', ' ');
    text += line + "\n";
  }
  WriteFileAtomically(path, text);
}

StagedDirectory::StagedDirectory(const std::string& directory, OutputKind kind)
    : directory_(Normalized(directory).string()), kind_(kind) {
  CheckOutputDirectory(directory, kind);
  std::string pattern = directory_ + ".partial-XXXXXX";
  if (mkdtemp(pattern.data()) == nullptr) {
    throw Error("cannot write '" + directory + "': cannot create '" + pattern +
                "': " + SystemReason());
  }
  staging_ = pattern;
}

StagedDirectory::~StagedDirectory() {
  if (committed_) return;
  std::error_code error;
  fs::remove_all(staging_, error);
}

std::string StagedDirectory::File(const std::string& name) const { return staging_ + "/" + name; }

void StagedDirectory::Commit() {
  CheckOutputDirectory(directory_, kind_);  // nothing foreign appeared meanwhile
  // The files in the staging directory were written without an fsync each (7 ms a file on
  // the development machine, seconds for a dataset's sweeps): one syncfs puts them all on
  // disk before the directory appears under its name.
  const int fd = open(staging_.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    syncfs(fd);
    close(fd);
  }
  // rename() replaces a missing or empty directory in one step.
  if (rename(staging_.c_str(), directory_.c_str()) != 0) {
    if (errno != ENOTEMPTY && errno != EEXIST) {
      throw Error("cannot move '" + staging_ + "' to '" + directory_ + "': " + SystemReason());
    }
    if (!ExchangeDirectories(staging_, directory_)) {
      // No exchange on this file system: the old result moves aside first, so that for a
      // moment there is no result at all, never a mixed one.
      const std::string old = staging_ + "-old";
      if (rename(directory_.c_str(), old.c_str()) != 0 ||
          rename(staging_.c_str(), directory_.c_str()) != 0) {
        throw Error("cannot replace '" + directory_ + "': " + SystemReason());
      }
      std::error_code error;
      fs::remove_all(old, error);
    }
    // After the exchange the staging name holds the previous result.
    std::error_code error;
    fs::remove_all(staging_, error);
  }
  committed_ = true;
  FsyncPath(fs::path(directory_).parent_path().string());
}

}  // namespace io
}  // namespace autocal
