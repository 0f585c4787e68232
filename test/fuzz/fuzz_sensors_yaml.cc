// libFuzzer target: ReadSensorsYaml (sensors.yaml) on arbitrary bytes.

#include <cstddef>
#include <cstdint>
#include <string>

#include "autocal/io/sensors_yaml.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace autocal;
  const std::string& path = fuzz::ScratchPath(".yaml");
  fuzz::WriteScratch(path, data, size);
  fuzz::ExpectParsedOrRefused([&] { io::ReadSensorsYaml(path); });
  return 0;
}
