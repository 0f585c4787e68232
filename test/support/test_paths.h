#pragma once

// Where tests find the shared real data and where they may write.

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace autocal {
namespace test {

// The shared data folder: $AUTOCAL_SHARED_DIR if set, else <project>/../shared.
inline std::filesystem::path SharedDir() {
  if (const char* env = std::getenv("AUTOCAL_SHARED_DIR")) return env;
  return std::filesystem::path(AUTOCAL_SOURCE_DIR).parent_path() / "shared";
}

inline std::filesystem::path SharedDataDir(const std::string& name) {
  return SharedDir() / "data" / name;
}

// A directory below the build tree (created on demand), private to the running test:
// ctest runs the tests of one program in parallel, so tests must never share files.
inline std::filesystem::path OutputDir(const std::string& name) {
  std::filesystem::path dir(AUTOCAL_TEST_OUTPUT_DIR);
  if (const auto* info = ::testing::UnitTest::GetInstance()->current_test_info()) {
    dir /= std::string(info->test_suite_name()) + "." + info->name();
  }
  dir /= name;
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace test
}  // namespace autocal

// Skips the current test with a clear message when a shared data folder is absent.
#define AUTOCAL_REQUIRE_SHARED_DATA(path)                                                    \
  do {                                                                                       \
    if (!std::filesystem::exists(path)) {                                                    \
      GTEST_SKIP() << "shared data not found at " << (path).string()                         \
                   << " (expected ../shared beside the project, or set AUTOCAL_SHARED_DIR)"; \
    }                                                                                        \
  } while (0)
