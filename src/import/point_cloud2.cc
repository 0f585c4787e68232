// sensor_msgs/PointCloud2 -> lidar::PointCloud with x, y, z, intensity and per-point time
// relative to the header stamp (docs/import.md, "Point time").

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "import/ros_messages.h"

namespace autocal {
namespace import {
namespace {

// sensor_msgs/PointField datatypes.
enum PointFieldType : uint8_t {
  kInt8 = 1,
  kUint8 = 2,
  kInt16 = 3,
  kUint16 = 4,
  kInt32 = 5,
  kUint32 = 6,
  kFloat32 = 7,
  kFloat64 = 8,
};

size_t FieldTypeBytes(uint8_t datatype) {
  switch (datatype) {
    case kInt8:
    case kUint8:
      return 1;
    case kInt16:
    case kUint16:
      return 2;
    case kInt32:
    case kUint32:
    case kFloat32:
      return 4;
    case kFloat64:
      return 8;
    default:
      return 0;
  }
}

bool IsIntegerType(uint8_t datatype) { return datatype >= kInt8 && datatype <= kUint32; }
bool IsFloatType(uint8_t datatype) { return datatype == kFloat32 || datatype == kFloat64; }

struct PointField {
  std::string name;
  uint32_t offset = 0;
  uint8_t datatype = 0;
  uint32_t count = 0;
};

template <typename T>
double Load(const char* p) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  return static_cast<double>(value);
}

// Reads one scalar field of a point, whatever its datatype.
double ReadField(const char* point, const PointField& field) {
  const char* p = point + field.offset;
  switch (field.datatype) {
    case kInt8:
      return Load<int8_t>(p);
    case kUint8:
      return Load<uint8_t>(p);
    case kInt16:
      return Load<int16_t>(p);
    case kUint16:
      return Load<uint16_t>(p);
    case kInt32:
      return Load<int32_t>(p);
    case kUint32:
      return Load<uint32_t>(p);
    case kFloat32:
      return Load<float>(p);
    default:
      return Load<double>(p);
  }
}

std::vector<PointField> ReadFields(MessageCursor* cursor) {
  const size_t min_string = cursor->serialization() == Serialization::kCdr ? 5 : 4;
  const uint32_t count = cursor->SequenceCount(min_string + 9);
  std::vector<PointField> fields(count);
  for (PointField& field : fields) {
    field.name = std::string(cursor->String());
    field.offset = cursor->U32();
    field.datatype = cursor->U8();
    field.count = cursor->U32();
  }
  return fields;
}

int FindField(const std::vector<PointField>& fields, const std::string& name) {
  for (size_t i = 0; i < fields.size(); ++i) {
    if (fields[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

// The layout a cloud declares, checked against its own sizes. Field indices are -1 when
// the cloud has no such field.
struct CloudLayout {
  std::vector<PointField> fields;
  uint32_t point_step = 0;
  uint32_t row_step = 0;
  std::string_view data;
  int x = -1, y = -1, z = -1, intensity = -1, time = -1;
  PointTimeForm time_form = PointTimeForm::kNone;
};

void CheckField(const MessageCursor& cursor, const PointField& field, uint32_t point_step) {
  const size_t bytes = FieldTypeBytes(field.datatype);
  if (bytes == 0) {
    cursor.Fail("PointCloud2 field '" + field.name + "' has unknown datatype " +
                std::to_string(field.datatype));
  }
  if (uint64_t{field.offset} + bytes > point_step) {
    cursor.Fail("PointCloud2 field '" + field.name + "' at offset " + std::to_string(field.offset) +
                " (" + std::to_string(bytes) + " bytes) does not fit in point_step " +
                std::to_string(point_step));
  }
}

// The time field by the names drivers use, checked for a datatype that fits its form.
void ChooseTimeField(const MessageCursor& cursor, CloudLayout* layout) {
  struct Form {
    const char* name;
    PointTimeForm form;
    bool integer;  // else floating point
  };
  static const Form kForms[] = {
      {"t", PointTimeForm::kRelativeNsU32, true},
      {"offset_time", PointTimeForm::kOffsetNsU32, true},
      {"time", PointTimeForm::kRelativeSecondsF32, false},
      {"timestamp", PointTimeForm::kAbsoluteSecondsF64, false},
  };
  for (const Form& form : kForms) {
    const int index = FindField(layout->fields, form.name);
    if (index < 0) continue;
    const uint8_t datatype = layout->fields[index].datatype;
    const bool fits = form.integer ? IsIntegerType(datatype) : IsFloatType(datatype);
    if (!fits) {
      cursor.Fail(std::string("PointCloud2 time field '") + form.name + "' has datatype " +
                  std::to_string(datatype) + ", expected " +
                  (form.integer ? "an integer (ns)" : "float32 or float64 (s)"));
    }
    layout->time = index;
    layout->time_form = form.form;
    return;
  }
}

// Reads fields .. is_dense and checks that point_step, row_step and data agree.
CloudLayout ReadLayout(MessageCursor* cursor, uint32_t height, uint32_t width) {
  CloudLayout layout;
  layout.fields = ReadFields(cursor);
  if (cursor->Bool()) cursor->Fail("big-endian PointCloud2 data is not supported");
  layout.point_step = cursor->U32();
  layout.row_step = cursor->U32();
  layout.data = cursor->Bytes(cursor->SequenceCount(1));
  cursor->Bool();  // is_dense

  const uint64_t points = uint64_t{height} * width;
  if (points > 0 && layout.point_step == 0) cursor->Fail("PointCloud2 has point_step 0");
  if (uint64_t{layout.row_step} < uint64_t{width} * layout.point_step ||
      uint64_t{layout.row_step} * height != layout.data.size()) {
    cursor->Fail("PointCloud2 sizes disagree: width " + std::to_string(width) + ", height " +
                 std::to_string(height) + ", point_step " + std::to_string(layout.point_step) +
                 ", row_step " + std::to_string(layout.row_step) + " but data holds " +
                 std::to_string(layout.data.size()) +
                 " bytes (expected row_step >= width * point_step and data = row_step * height)");
  }
  layout.x = FindField(layout.fields, "x");
  layout.y = FindField(layout.fields, "y");
  layout.z = FindField(layout.fields, "z");
  if (layout.x < 0 || layout.y < 0 || layout.z < 0) {
    cursor->Fail("PointCloud2 has no x, y and z fields");
  }
  layout.intensity = FindField(layout.fields, "intensity");
  ChooseTimeField(*cursor, &layout);
  for (int index : {layout.x, layout.y, layout.z, layout.intensity, layout.time}) {
    if (index >= 0) CheckField(*cursor, layout.fields[index], layout.point_step);
  }
  return layout;
}

// A point's time relative to the header stamp, in seconds, for the cloud's time form.
class PointTimeReader {
 public:
  PointTimeReader(const CloudLayout& layout, int64_t stamp_ns)
      : form_(layout.time_form), stamp_ns_(stamp_ns) {
    if (layout.time >= 0) field_ = layout.fields[layout.time];
  }

  double Seconds(const char* point) const {
    switch (form_) {
      case PointTimeForm::kNone:
        return 0.0;
      case PointTimeForm::kRelativeNsU32:
      case PointTimeForm::kOffsetNsU32:
        return ReadField(point, field_) * 1e-9;
      case PointTimeForm::kRelativeSecondsF32:
        return ReadField(point, field_);
      case PointTimeForm::kAbsoluteSecondsF64:
        return Absolute(ReadField(point, field_));
    }
    return 0.0;
  }

 private:
  // Absolute seconds minus the stamp, whole seconds first so that no digit is lost; a
  // value beyond 1e15 is taken as absolute nanoseconds (drivers that write ns there).
  double Absolute(double value) const {
    if (value > 1e15) return (value - static_cast<double>(stamp_ns_)) * 1e-9;
    const double whole_s = std::floor(value);
    const int64_t stamp_s = stamp_ns_ / 1000000000;
    const double stamp_frac_s = static_cast<double>(stamp_ns_ % 1000000000) * 1e-9;
    return (whole_s - static_cast<double>(stamp_s)) + (value - whole_s) - stamp_frac_s;
  }

  PointTimeForm form_;
  int64_t stamp_ns_;
  PointField field_;
};

}  // namespace

PointCloudMessage DecodePointCloud2(MessageCursor* cursor) {
  PointCloudMessage message;
  message.stamp_ns = cursor->Header(&message.frame_id);
  message.height = cursor->U32();
  message.width = cursor->U32();
  const CloudLayout layout = ReadLayout(cursor, message.height, message.width);
  message.time_form = layout.time_form;
  const PointTimeReader time_reader(layout, message.stamp_ns);

  const int64_t capacity = int64_t{message.height} * message.width;
  // No points: nothing to read (and no loop over up to 2^32 rows of width 0).
  if (capacity == 0) return message;
  lidar::PointCloud& cloud = message.cloud;
  cloud.points.resize(3, capacity);
  cloud.time_s.resize(capacity);
  if (layout.intensity >= 0) cloud.intensity.resize(capacity);
  int64_t kept = 0;
  for (uint32_t row = 0; row < message.height; ++row) {
    const char* row_data = layout.data.data() + size_t{row} * layout.row_step;
    for (uint32_t col = 0; col < message.width; ++col) {
      const char* point = row_data + size_t{col} * layout.point_step;
      const Eigen::Vector3d p(ReadField(point, layout.fields[layout.x]),
                              ReadField(point, layout.fields[layout.y]),
                              ReadField(point, layout.fields[layout.z]));
      if (!p.allFinite() || p.isZero(0.0)) {
        ++message.dropped_points;
        continue;
      }
      const double t_s = time_reader.Seconds(point);
      if (!(std::abs(t_s) <= lidar::kMaxPointTimeS)) {
        cursor->Fail("point " + std::to_string(size_t{row} * message.width + col) + " has time " +
                     std::to_string(t_s) + " s from the header stamp in the " +
                     PointTimeFormName(layout.time_form) +
                     " form: not a time within one sweep (limit 1 s)");
      }
      cloud.points.col(kept) = p;
      cloud.time_s[kept] = t_s;
      if (layout.intensity >= 0) {
        cloud.intensity[kept] =
            static_cast<float>(ReadField(point, layout.fields[layout.intensity]));
      }
      ++kept;
    }
  }
  cloud.points.conservativeResize(3, kept);
  cloud.time_s.conservativeResize(kept);
  if (layout.intensity >= 0) cloud.intensity.conservativeResize(kept);
  return message;
}

}  // namespace import
}  // namespace autocal
