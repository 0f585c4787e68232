#include "autocal/io/output_files.h"

#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "io/text_format.h"
#include "support/test_paths.h"

namespace autocal {
namespace io {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::string Read(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void Touch(const fs::path& path, const std::string& text = "x") {
  std::ofstream(path, std::ios::binary) << text;
}

// The names in `directory`, sorted.
std::vector<std::string> Names(const fs::path& directory) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(directory))
    names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// test::OutputDir(name), emptied: an earlier run of the test leaves nothing behind.
fs::path CleanDir(const std::string& name) {
  const fs::path dir = test::OutputDir(name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void ExpectRefused(const std::function<void()>& call, const std::string& message) {
  try {
    call();
    ADD_FAILURE() << "not refused; expected '" << message << "'";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr(message));
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line: " << e.what();
  }
}

TEST(OutputFilesTest, ABadOutputLocationIsRefusedBeforeAnyWork) {
  const fs::path root = CleanDir("check");
  Touch(root / "a_file");
  ExpectRefused([&] { CheckOutputDirectory((root / "a_file").string(), OutputKind::kResult); },
                "it exists and is not a directory");
  ExpectRefused(
      [&] { CheckOutputDirectory((root / "missing" / "out").string(), OutputKind::kResult); },
      "the directory '" + (root / "missing").string() + "' does not exist");
  ExpectRefused([&] { CheckOutputFile((root / "missing" / "r.yaml").string()); }, "does not exist");
  ExpectRefused([&] { CheckOutputFile(root.string()); }, "it is a directory");
  // A directory with anything but result files is never replaced.
  fs::create_directories(root / "home");
  Touch(root / "home" / "notes.txt");
  Touch(root / "home" / "calibration.yaml");
  ExpectRefused([&] { CheckOutputDirectory((root / "home").string(), OutputKind::kResult); },
                "holds 'notes.txt', which is not part of an autocal result");
  ExpectRefused([&] { CheckOutputDirectory((root / "home").string(), OutputKind::kDataset); },
                "which is not part of an autocal dataset");
  // Missing, empty or a previous result: fine; a trailing separator changes nothing.
  EXPECT_NO_THROW(CheckOutputDirectory((root / "new").string(), OutputKind::kResult));
  fs::create_directories(root / "result");
  Touch(root / "result" / "calibration.yaml");
  Touch(root / "result" / "trajectory.tum");
  EXPECT_NO_THROW(CheckOutputDirectory((root / "result").string() + "/", OutputKind::kResult));
  if (geteuid() != 0) {  // root may write anywhere
    fs::create_directories(root / "locked");
    fs::permissions(root / "locked", fs::perms::owner_read | fs::perms::owner_exec);
    ExpectRefused(
        [&] { CheckOutputDirectory((root / "locked" / "out").string(), OutputKind::kResult); },
        "cannot create files in");
    fs::permissions(root / "locked", fs::perms::owner_all);
  }
}

TEST(OutputFilesTest, AStagedDirectoryAppearsWholeOrNotAtAll) {
  const fs::path root = CleanDir("staged");
  const fs::path out = root / "result";
  {
    StagedDirectory staged(out.string(), OutputKind::kResult);
    Touch(staged.File("calibration.yaml"));
    EXPECT_FALSE(fs::exists(out));
    EXPECT_THAT(staged.staging(), HasSubstr("result.partial-"));
    // No Commit(): a failed run.
  }
  EXPECT_FALSE(fs::exists(out));
  EXPECT_THAT(Names(root), ::testing::IsEmpty());
  {
    StagedDirectory staged(out.string(), OutputKind::kResult);
    Touch(staged.File("calibration.yaml"), "first");
    Touch(staged.File("report.html"));
    staged.Commit();
  }
  EXPECT_EQ(Read(out / "calibration.yaml"), "first");
  // A second result replaces the first as a whole: no file of the first stays.
  {
    StagedDirectory staged((out.string() + "/"), OutputKind::kResult);
    Touch(staged.File("calibration.yaml"), "second");
    staged.Commit();
  }
  EXPECT_EQ(Read(out / "calibration.yaml"), "second");
  EXPECT_THAT(Names(out), ::testing::ElementsAre("calibration.yaml"));
  EXPECT_THAT(Names(root), ::testing::ElementsAre("result"));
  // A foreign file appearing during the run stops the replacement; the staging goes away.
  {
    StagedDirectory staged(out.string(), OutputKind::kResult);
    Touch(staged.File("calibration.yaml"), "third");
    Touch(out / "mine.txt");
    ExpectRefused([&] { staged.Commit(); }, "holds 'mine.txt'");
  }
  EXPECT_EQ(Read(out / "calibration.yaml"), "second");
  EXPECT_THAT(Names(root), ::testing::ElementsAre("result"));
}

TEST(OutputFilesTest, AFileIsReplacedAtomically) {
  const fs::path root = CleanDir("atomic");
  const std::string path = (root / "a.yaml").string();
  WriteFileAtomically(path, "one\n");
  WriteFileAtomically(path, "two\n");
  EXPECT_EQ(Read(path), "two\n");
  EXPECT_THAT(Names(root), ::testing::ElementsAre("a.yaml"));  // no temporary left
  ExpectRefused([&] { WriteFileAtomically(root.string(), "x"); }, "it is a directory");
  ExpectRefused(
      [&] { WriteFileAtomically((root / "no" / "a.yaml").string(), "x"); },
      "cannot write '" + (root / "no" / "a.yaml").string() + "': No such file or directory");
}

// A full disk names the file and the reason (/dev/full fails every write with ENOSPC).
TEST(OutputFilesTest, AFullDiskSaysSo) {
  const int fd = open("/dev/full", O_WRONLY | O_CLOEXEC);
  if (fd < 0) GTEST_SKIP() << "/dev/full is not available";
  ExpectRefused([&] { internal::WriteAllToDescriptor(fd, "some bytes", "out/result.yaml"); },
                "cannot write 'out/result.yaml': No space left on device");
  close(fd);
}

}  // namespace
}  // namespace io
}  // namespace autocal
