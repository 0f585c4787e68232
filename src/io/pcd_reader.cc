// PCD reader (PCL's format, v0.7): a text header of KEY value lines ending with DATA,
// then one point per line (ascii) or packed little-endian records (binary).
// binary_compressed (LZF) is not supported and says so.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "io/byte_source.h"
#include "io/checked_math.h"
#include "io/point_cloud_builder.h"
#include "io/point_cloud_formats.h"
#include "io/scalar_type.h"
#include "io/text_format.h"

namespace autocal {
namespace io {
namespace internal {
namespace {

struct PcdField {
  std::string name;
  ScalarType type = ScalarType::kFloat32;
  int64_t count = 1;
  int64_t count_column = 0;  // of its COUNT value, 0 without a COUNT line
  size_t offset = 0;         // byte offset inside a binary record
  int role = -1;             // PointValue filled by this field, -1 when skipped
};

enum class PcdData { kAscii, kBinary };

class PcdParser {
 public:
  PcdParser(const std::string& path, const std::string& bytes, const PointCloudReadOptions& options)
      : source_(path, bytes), options_(options) {}

  lidar::PointCloud Parse() {
    ParseHeader();
    ResolveRoles();
    return data_ == PcdData::kAscii ? ReadAscii() : ReadBinary();
  }

 private:
  int64_t ParseCount(const Word& word, int64_t min_value) const {
    const int64_t value = source_.IntegerAt(word.text, source_.line(), word.column);
    if (value < min_value) {
      source_.FailAtColumn(word.column, "expected an integer >= " + std::to_string(min_value) +
                                            ", found " + Quote(word.text));
    }
    return value;
  }

  // One value per field; its count must match FIELDS.
  void CheckPerField(const std::vector<Word>& words) const {
    if (fields_.empty()) source_.FailAtColumn(1, Quote(words[0].text) + " before FIELDS");
    if (words.size() - 1 != fields_.size()) {
      source_.FailAtColumn(words[0].column,
                           Quote(words[0].text) + " has " + std::to_string(words.size() - 1) +
                               " values but FIELDS names " + std::to_string(fields_.size()));
    }
  }

  // A header key may appear once: a second FIELDS would leave SIZE and TYPE describing
  // other fields than the ones read.
  void CheckFirstOccurrence(const Word& key) {
    const auto [first, inserted] = key_lines_.emplace(std::string(key.text), source_.line());
    if (!inserted) {
      source_.FailAtColumn(key.column, "second " + Quote(key.text) +
                                           " line in the PCD header (the first is line " +
                                           std::to_string(first->second) + ")");
    }
  }

  // COUNT values; their sum (values per point) must fit in int64.
  void ParseCounts(const std::vector<Word>& words) {
    CheckPerField(words);
    count_line_ = source_.line();
    int64_t values_per_point = 0;
    for (size_t i = 1; i < words.size(); ++i) {
      PcdField& field = fields_[i - 1];
      field.count = ParseCount(words[i], 1);
      field.count_column = words[i].column;
      if (!CheckedAdd(values_per_point, field.count, &values_per_point)) {
        source_.FailAtColumn(words[i].column,
                             "COUNT values add up to more than " +
                                 std::to_string(std::numeric_limits<int64_t>::max()) +
                                 " values per point");
      }
    }
    values_per_point_ = values_per_point;
  }

  void ParseHeader() {
    if (source_.size() == 0)
      source_.FailAtByte(0, "empty file; a PCD file starts with its header (VERSION, FIELDS, ...)");
    std::vector<Word> sizes;
    std::vector<Word> types;
    int64_t sizes_line = 0;
    int64_t types_line = 0;
    std::string_view line;
    while (source_.NextLine(&line)) {
      const std::vector<Word> words = SplitWords(line);
      if (words.empty() || words[0].text[0] == '#') continue;
      const std::string_view key = words[0].text;
      CheckFirstOccurrence(words[0]);
      if (key == "VERSION" || key == "VIEWPOINT") continue;
      if (key == "FIELDS") {
        for (size_t i = 1; i < words.size(); ++i) fields_.push_back({std::string(words[i].text)});
        if (fields_.empty()) source_.FailAtColumn(1, "FIELDS names no field");
        values_per_point_ = static_cast<int64_t>(fields_.size());
      } else if (key == "SIZE") {
        CheckPerField(words);
        sizes = words;
        sizes_line = source_.line();
      } else if (key == "TYPE") {
        CheckPerField(words);
        types = words;
        types_line = source_.line();
      } else if (key == "COUNT") {
        ParseCounts(words);
      } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
        if (words.size() != 2)
          source_.FailAtColumn(1, "expected '" + std::string(key) + " <integer>'");
        const int64_t value = ParseCount(words[1], 0);
        (key == "WIDTH" ? width_ : key == "HEIGHT" ? height_ : points_) = value;
      } else if (key == "DATA") {
        if (words.size() != 2) source_.FailAtColumn(1, "expected 'DATA ascii' or 'DATA binary'");
        if (words[1].text == "ascii") {
          data_ = PcdData::kAscii;
        } else if (words[1].text == "binary") {
          data_ = PcdData::kBinary;
        } else if (words[1].text == "binary_compressed") {
          source_.FailAtColumn(
              words[1].column,
              "PCD 'DATA binary_compressed' is unsupported; convert the file to binary or "
              "ascii (e.g. with PCL's pcl_convert_pcd_ascii_binary)");
        } else {
          source_.FailAtColumn(words[1].column, "unknown PCD DATA kind " + Quote(words[1].text));
        }
        data_line_ = source_.line();
        ResolveTypes(sizes, sizes_line, types, types_line);
        ResolvePointCount();
        return;
      } else {
        source_.FailAtColumn(words[0].column, "unknown PCD header key " + Quote(key));
      }
    }
    source_.FailAtByte(
        source_.size(),
        "file ends inside the PCD header (no DATA line): truncated or not a PCD file");
  }

  void ResolveTypes(const std::vector<Word>& sizes, int64_t sizes_line,
                    const std::vector<Word>& types, int64_t types_line) {
    if (fields_.empty()) source_.FailAt(data_line_, 1, "PCD header has no FIELDS line");
    if (sizes.empty()) source_.FailAt(data_line_, 1, "PCD header has no SIZE line");
    if (types.empty()) source_.FailAt(data_line_, 1, "PCD header has no TYPE line");
    size_t offset = 0;
    for (size_t i = 0; i < fields_.size(); ++i) {
      const Word& size_word = sizes[i + 1];
      const Word& type_word = types[i + 1];
      const std::string_view t = type_word.text;
      const std::string_view s = size_word.text;
      std::optional<ScalarType> type;
      if (t == "F") {
        if (s == "4") type = ScalarType::kFloat32;
        if (s == "8") type = ScalarType::kFloat64;
      } else if (t == "I") {
        if (s == "1") type = ScalarType::kInt8;
        if (s == "2") type = ScalarType::kInt16;
        if (s == "4") type = ScalarType::kInt32;
      } else if (t == "U") {
        if (s == "1") type = ScalarType::kUint8;
        if (s == "2") type = ScalarType::kUint16;
        if (s == "4") type = ScalarType::kUint32;
      } else {
        source_.FailAt(types_line, type_word.column,
                       "unknown PCD TYPE " + Quote(t) + " (expected I, U or F)");
      }
      if (!type) {
        source_.FailAt(sizes_line, size_word.column,
                       "unsupported SIZE " + Quote(s) + " for TYPE " + std::string(t) +
                           " of field '" + fields_[i].name +
                           "' (supported: F 4/8, I 1/2/4, U 1/2/4)");
      }
      fields_[i].type = *type;
      fields_[i].offset = offset;
      size_t field_bytes = 0;
      if (!CheckedMultiply(ScalarSize(*type), static_cast<size_t>(fields_[i].count),
                           &field_bytes) ||
          !CheckedAdd(offset, field_bytes, &offset)) {
        source_.FailAt(count_line_, fields_[i].count_column,
                       "COUNT " + std::to_string(fields_[i].count) + " of field '" +
                           fields_[i].name + "' makes a point record larger than " +
                           std::to_string(std::numeric_limits<size_t>::max()) + " bytes");
      }
    }
    record_size_ = offset;
  }

  void ResolvePointCount() {
    if (width_ < 0) source_.FailAt(data_line_, 1, "PCD header has no WIDTH line");
    if (height_ < 0) height_ = 1;
    if (height_ > 0 && width_ > std::numeric_limits<int64_t>::max() / height_) {
      source_.FailAt(data_line_, 1, "PCD WIDTH x HEIGHT overflows");
    }
    if (points_ < 0) points_ = width_ * height_;
    if (points_ != width_ * height_) {
      source_.FailAt(data_line_, 1,
                     "PCD header says POINTS " + std::to_string(points_) +
                         " but WIDTH x HEIGHT = " + std::to_string(width_ * height_));
    }
  }

  void ResolveRoles() {
    const auto find = [&](std::string_view name) -> int {
      for (size_t i = 0; i < fields_.size(); ++i) {
        if (fields_[i].name == name) return static_cast<int>(i);
      }
      return -1;
    };
    const char* const kAxes[] = {"x", "y", "z"};
    for (int axis = 0; axis < 3; ++axis) {
      const int i = find(kAxes[axis]);
      if (i < 0) {
        source_.FailAt(
            data_line_, 1,
            std::string("PCD FIELDS has no '") + kAxes[axis] + "'; a point cloud needs x, y and z");
      }
      if (fields_[i].count != 1) {
        source_.FailAt(data_line_, 1,
                       std::string("PCD field '") + kAxes[axis] + "' has COUNT != 1");
      }
      fields_[i].role = axis;
    }
    // The field that fills `role`, or -1.
    const auto assign_optional = [&](int role, std::string_view first, std::string_view second) {
      int i = find(first);
      if (i < 0) i = find(second);
      if (i < 0 || fields_[i].count != 1) return -1;
      fields_[i].role = role;
      return i;
    };
    has_intensity_ = assign_optional(kIntensity, "intensity", "scalar_intensity") >= 0;
    const int time = assign_optional(kTime, "t", "time");
    time_ = PointTimeOf(time >= 0, time >= 0 ? fields_[time].type : ScalarType::kFloat32);
  }

  void AddPoint(PointCloudBuilder* builder, const double (&values)[kNumPointValues], int64_t index,
                int64_t line, size_t byte_offset) const {
    int bad = 0;
    const PointCloudBuilder::AddResult result = builder->Add(values, &bad);
    FailOnRefusedPoint(result, "point", index, bad, values, time_, [&](const std::string& message) {
      source_.FailAtLineOrByte(line, byte_offset, message);
    });
  }

  lidar::PointCloud ReadAscii() {
    const int64_t values_per_line = values_per_point_;
    // A line holds at least x, y and z, each a character and a separator (the last line's
    // newline may be missing): a count the bytes cannot hold is refused before the points are
    // allocated. A line too short for its COUNT values is named at its line below.
    const uint64_t most_points = (source_.remaining() + 1) / 6;
    if (static_cast<uint64_t>(points_) > most_points) {
      source_.FailAtByte(source_.size(), "file ends at byte " + std::to_string(source_.size()) +
                                             " but the header declares " + std::to_string(points_) +
                                             " points: truncated?");
    }
    PointCloudBuilder builder(points_, has_intensity_, time_, options_.drop_non_finite_points);
    for (int64_t i = 0; i < points_; ++i) {
      std::string_view line;
      if (!source_.NextLine(&line)) {
        source_.FailAtByte(source_.size(), "file ends after " + std::to_string(i) + " of " +
                                               std::to_string(points_) + " points: truncated?");
      }
      const std::vector<Word> words = SplitWords(line);
      if (static_cast<int64_t>(words.size()) != values_per_line) {
        const int64_t column = static_cast<int64_t>(words.size()) > values_per_line
                                   ? words[values_per_line].column
                                   : static_cast<int64_t>(line.size()) + 1;
        source_.FailAtColumn(column, "expected " + std::to_string(values_per_line) +
                                         " values, found " + std::to_string(words.size()));
      }
      double values[kNumPointValues] = {0.0, 0.0, 0.0, 0.0, 0.0};
      size_t w = 0;
      for (const PcdField& field : fields_) {
        if (field.role >= 0) {
          values[field.role] = source_.DoubleAt(words[w].text, source_.line(), words[w].column);
        }
        w += static_cast<size_t>(field.count);
      }
      AddPoint(&builder, values, i, source_.line(), 0);
    }
    // Points beyond the declared count (a writer that never updated POINTS) would otherwise be
    // dropped silently; blank lines may follow.
    std::string_view line;
    while (source_.NextLine(&line)) {
      const std::vector<Word> words = SplitWords(line);
      if (!words.empty()) source_.FailAtColumn(words.front().column, DataAfterThePoints());
    }
    return builder.Finish();
  }

  std::string DataAfterThePoints() const {
    return "data after the " + std::to_string(points_) + " points the header declares (POINTS " +
           std::to_string(points_) + ")";
  }

  lidar::PointCloud ReadBinary() {
    const size_t remaining = source_.remaining();
    if (record_size_ == 0 || static_cast<uint64_t>(points_) > remaining / record_size_) {
      source_.FailAtByte(source_.size(), "file ends at byte " + std::to_string(source_.size()) +
                                             " but the header declares " + std::to_string(points_) +
                                             " points of " + std::to_string(record_size_) +
                                             " bytes after byte " + std::to_string(source_.pos()) +
                                             ": truncated?");
    }
    PointCloudBuilder builder(points_, has_intensity_, time_, options_.drop_non_finite_points);
    for (int64_t i = 0; i < points_; ++i) {
      const size_t record = source_.pos() + static_cast<size_t>(i) * record_size_;
      double values[kNumPointValues] = {0.0, 0.0, 0.0, 0.0, 0.0};
      for (const PcdField& field : fields_) {
        if (field.role < 0) continue;
        // PCD binary data is a memory dump of little-endian machines.
        values[field.role] =
            DecodeScalar(source_.bytes().data() + record + field.offset, field.type, true);
      }
      AddPoint(&builder, values, i, 0, record);
    }
    const size_t end = source_.pos() + static_cast<size_t>(points_) * record_size_;
    if (end < source_.size()) {
      source_.FailAtByte(
          end, std::to_string(source_.size() - end) + " bytes of " + DataAfterThePoints());
    }
    return builder.Finish();
  }

  ByteSource source_;
  const PointCloudReadOptions& options_;
  int64_t data_line_ = 0;
  int64_t count_line_ = 0;
  std::map<std::string, int64_t> key_lines_;  // header key -> its line
  std::vector<PcdField> fields_;
  int64_t values_per_point_ = 0;  // the sum of COUNT
  int64_t width_ = -1;
  int64_t height_ = -1;
  int64_t points_ = -1;
  size_t record_size_ = 0;
  PcdData data_ = PcdData::kAscii;
  bool has_intensity_ = false;
  PointTime time_ = PointTime::kNone;
};

}  // namespace

lidar::PointCloud ParsePcd(const std::string& path, const std::string& bytes,
                           const PointCloudReadOptions& options) {
  return PcdParser(path, bytes, options).Parse();
}

}  // namespace internal
}  // namespace io
}  // namespace autocal
