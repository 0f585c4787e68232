// libFuzzer target: ReadTumTrajectory (TUM trajectory files) on arbitrary bytes.

#include <cstddef>
#include <cstdint>
#include <string>

#include "autocal/io/tum_trajectory.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace autocal;
  const std::string& path = fuzz::ScratchPath(".tum");
  fuzz::WriteScratch(path, data, size);
  fuzz::ExpectParsedOrRefused([&] { io::ReadTumTrajectory(path); });
  return 0;
}
