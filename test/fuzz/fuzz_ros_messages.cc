// libFuzzer target: the ROS message decoders on arbitrary bytes. Byte 0 chooses the message
// type (low bits, modulo the seven supported types) and the serialization (bit 7 set: CDR,
// else ROS 1); the rest is the serialized message.

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz_bag_messages.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace autocal;
  if (size == 0) return 0;
  constexpr int kKinds = static_cast<int>(import::MessageKind::kOther);
  const auto kind = static_cast<import::MessageKind>((data[0] & 0x7f) % kKinds);
  const auto serialization =
      (data[0] & 0x80) != 0 ? import::Serialization::kCdr : import::Serialization::kRos1;
  import::MessageContext context;
  context.location.file = "fuzz.bag";
  context.type = "fuzz";
  const std::string_view message(reinterpret_cast<const char*>(data) + 1, size - 1);
  fuzz::ExpectParsedOrRefused([&] { fuzz::DecodeMessage(kind, message, serialization, context); });
  return 0;
}
