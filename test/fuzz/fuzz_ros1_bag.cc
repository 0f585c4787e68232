// libFuzzer target: the ROS 1 bag reader on arbitrary bytes, every message read and each of
// a supported type decoded.

#include <cstddef>
#include <cstdint>

#include "fuzz_bag_messages.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace autocal;
  const std::string& path = fuzz::ScratchPath(".bag");
  fuzz::WriteScratch(path, data, size);
  fuzz::ExpectParsedOrRefused([&] { fuzz::ReadAndDecodeAll(import::OpenRos1Bag(path).get()); });
  return 0;
}
