// libFuzzer target: the rosbag2 metadata.yaml parser on arbitrary bytes.

#include <cstddef>
#include <cstdint>

#include "fuzz_input.h"
#include "import/rosbag2_metadata.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace autocal;
  const std::string& path = fuzz::ScratchPath("_metadata.yaml");
  fuzz::WriteScratch(path, data, size);
  fuzz::ExpectParsedOrRefused([&] { import::internal::ReadRosbag2Metadata(path); });
  return 0;
}
