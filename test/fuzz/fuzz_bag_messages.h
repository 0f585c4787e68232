#pragma once

// Shared by the bag fuzz targets: decodes one message with the decoder its type selects, and
// reads every message of a bag, decoding those of a supported type. Decoding only: what the
// importer does with the values is not a parsing question.

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>

#include "autocal/common/error.h"
#include "import/bag_reader.h"
#include "import/message_cursor.h"
#include "import/ros_messages.h"

namespace autocal {
namespace fuzz {

// Decodes `data` as a message of `kind` (nothing for kOther).
inline void DecodeMessage(import::MessageKind kind, std::string_view data,
                          import::Serialization serialization,
                          const import::MessageContext& context) {
  using import::MessageKind;
  if (kind == MessageKind::kOther) return;
  import::MessageCursor cursor(data, serialization, &context);
  switch (kind) {
    case MessageKind::kImu:
      import::DecodeImu(&cursor);
      break;
    case MessageKind::kPointCloud2:
      import::DecodePointCloud2(&cursor);
      break;
    case MessageKind::kOdometry:
      import::DecodeOdometry(&cursor);
      break;
    case MessageKind::kTwistStamped:
      import::DecodeTwistStamped(&cursor);
      break;
    case MessageKind::kJointState:
      import::DecodeJointState(&cursor);
      break;
    case MessageKind::kNavSatFix:
      import::DecodeNavSatFix(&cursor);
      break;
    case MessageKind::kTfMessage:
      import::DecodeTfMessage(&cursor);
      break;
    case MessageKind::kOther:
      break;
  }
}

// Reads `reader` to its end; each message of a supported type is decoded. A message the
// decoder refuses does not end the bag (the reader goes on, as a caller skipping it would).
inline void ReadAndDecodeAll(import::BagReader* reader) {
  // Ids are the file's own (any uint32 in a ROS 1 bag): a map, not a table indexed by them.
  std::map<uint32_t, const import::Connection*> by_id;
  for (const import::Connection& connection : reader->connections()) {
    by_id[connection.id] = &connection;
  }
  reader->IndexedTopics();
  import::MessageContext context;
  import::BagMessage message;
  while (reader->Next(&message)) {
    const auto found = by_id.find(message.connection_id);
    if (found == by_id.end()) continue;
    const import::Connection* connection = found->second;
    context.location = import::MessageLocation(reader->path(), message);
    context.type = import::NormalizedTypeName(connection->type);
    context.topic = connection->topic;
    try {
      DecodeMessage(import::KindOfType(connection->type), message.data, connection->serialization,
                    context);
    } catch (const Error&) {
    }
  }
}

}  // namespace fuzz
}  // namespace autocal
