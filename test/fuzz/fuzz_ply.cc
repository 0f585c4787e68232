// libFuzzer target: the PLY reader on arbitrary bytes, with both non-finite policies.

#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_input.h"
#include "io/point_cloud_formats.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace autocal;
  const std::string bytes(reinterpret_cast<const char*>(data), size);
  for (const bool drop : {false, true}) {
    io::PointCloudReadOptions options;
    options.drop_non_finite_points = drop;
    fuzz::ExpectParsedOrRefused([&] { io::internal::ParsePly("fuzz.ply", bytes, options); });
  }
  return 0;
}
