#pragma once

// Runs one of the built tools (tools/autocal_*) the way a shell would, for the tests of their
// command lines. The test's CMake entry defines AUTOCAL_TOOL_DIR (test/CMakeLists.txt).

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <string>

#ifndef AUTOCAL_TOOL_DIR
#error "test/CMakeLists.txt defines AUTOCAL_TOOL_DIR for this test"
#endif

namespace autocal {
namespace test {

struct ToolOutput {
  int exit_code = -1;  // -1 when it could not be started or ended by a signal
  std::string text;    // stdout and stderr
};

// `tool` with `args` (one shell word string, quoted by the caller where needed).
inline ToolOutput RunTool(const std::string& tool, const std::string& args) {
  const std::string command =
      (std::filesystem::path(AUTOCAL_TOOL_DIR) / tool).string() + " " + args + " 2>&1";
  ToolOutput out;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return out;
  char buffer[4096];
  size_t n = 0;
  while ((n = fread(buffer, 1, sizeof(buffer), pipe)) > 0) out.text.append(buffer, n);
  const int status = pclose(pipe);
  out.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return out;
}

}  // namespace test
}  // namespace autocal
