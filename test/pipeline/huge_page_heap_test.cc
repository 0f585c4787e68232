// tools::StartWithHugePageHeap as the tools call it: the program runs itself again, once, with
// glibc's malloc.hugetlb tunable added to the environment's tunables, and leaves a
// GLIBC_TUNABLES that already names the tunable alone. Each case forks; the child calls it with
// the arguments of this program's ReportsTheEnvironment test, which writes what the restarted
// program sees to a file the parent reads.

#include <gtest/gtest.h>
#include <malloc.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "support/test_paths.h"
#include "tools/keep_freed_memory.h"

namespace autocal {
namespace {

constexpr const char* kReportTo = "AUTOCAL_TEST_HEAP_REPORT";

std::string Read(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

void WriteEnvironment(const char* path) {
  std::ofstream out(path);
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  out << "pid " << getpid() << "\ntunables " << (tunables != nullptr ? tunables : "(none)") << "\n";
}

// What the program run with `tunables` in GLIBC_TUNABLES (nullptr: unset) sees after
// StartWithHugePageHeap, and whether that was a new program in the same process.
struct Seen {
  std::string tunables;
  bool same_pid = false;
};

Seen RunWith(const char* tunables, const std::string& name) {
  const std::filesystem::path report = test::OutputDir("huge_page_heap") / (name + ".txt");
  std::filesystem::remove(report);
  const pid_t child = fork();
  if (child == 0) {
    if (tunables != nullptr) {
      setenv("GLIBC_TUNABLES", tunables, 1);
    } else {
      unsetenv("GLIBC_TUNABLES");
    }
    unsetenv("AUTOCAL_HEAP_TUNED");
    setenv(kReportTo, report.c_str(), 1);
    std::string self = std::filesystem::read_symlink("/proc/self/exe").string();
    std::string filter = "--gtest_filter=HugePageHeap.ReportsTheEnvironment";
    char* argv[] = {self.data(), filter.data(), nullptr};
    tools::StartWithHugePageHeap(argv);
    // Not run again: report from here.
    WriteEnvironment(report.c_str());
    _exit(0);
  }
  int status = 0;
  waitpid(child, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << name;
  const std::string text = Read(report);
  Seen seen;
  std::istringstream lines(text);
  std::string key, pid;
  lines >> key >> pid >> key;
  std::getline(lines >> std::ws, seen.tunables);
  seen.same_pid = pid == std::to_string(child);
  return seen;
}

// The restarted program's side: only when the test above asked for it.
TEST(HugePageHeap, ReportsTheEnvironment) {
  const char* report = std::getenv(kReportTo);
  if (report == nullptr) GTEST_SKIP() << "run by the other HugePageHeap tests";
  WriteEnvironment(report);
}

TEST(HugePageHeap, RestartsOnceWithTheTunable) {
  const Seen seen = RunWith(nullptr, "unset");
  EXPECT_EQ(seen.tunables, "glibc.malloc.hugetlb=1");
  EXPECT_TRUE(seen.same_pid);
}

TEST(HugePageHeap, KeepsTheOtherTunables) {
  const Seen seen = RunWith("glibc.malloc.check=0", "other");
  EXPECT_EQ(seen.tunables, "glibc.malloc.check=0:glibc.malloc.hugetlb=1");
}

TEST(HugePageHeap, LeavesAGivenSettingAlone) {
  const Seen seen = RunWith("glibc.malloc.hugetlb=0", "given");
  EXPECT_EQ(seen.tunables, "glibc.malloc.hugetlb=0");
  EXPECT_TRUE(seen.same_pid);
}

// tools::KeepFreedMemory: a block of hundreds of MiB, as a long log's solver matrices, comes
// from the heap and stays there once freed, so the next solve reuses it without page faults.
// In a child, so this process's allocator keeps its settings.
TEST(KeepFreedMemory, KeepsALargeFreedBlockOnTheHeap) {
  const pid_t child = fork();
  if (child == 0) {
    tools::KeepFreedMemory();
    constexpr size_t kBytes = size_t{300} << 20;
    char* block = static_cast<char*>(std::malloc(kBytes));
    if (block == nullptr) _exit(2);
    std::memset(block, 1, kBytes);
    const struct mallinfo2 held = mallinfo2();
    std::free(block);
    const struct mallinfo2 freed = mallinfo2();
    // Not mapped on its own (hblkhd), and its pages still the heap's after the free.
    const bool on_heap = held.hblkhd == 0 && held.arena >= kBytes;
    const bool kept = freed.arena >= kBytes && freed.fordblks >= kBytes;
    _exit(on_heap && kept ? 0 : 1);
  }
  int status = 0;
  waitpid(child, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "1: the block was mapped or trimmed; 2: no memory";
}

}  // namespace
}  // namespace autocal
