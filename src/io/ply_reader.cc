// PLY reader (http://paulbourke.net/dataformats/ply/): a text header declaring elements
// and their properties, then the body in ascii or binary of either endianness. Only the
// `vertex` element is read; elements before it are parsed to be skipped, elements after it
// (faces, ...) are ignored.

#include <algorithm>
#include <cstdint>
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

enum class PlyFormat { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

struct PlyProperty {
  std::string name;
  ScalarType type = ScalarType::kFloat32;
  bool is_list = false;
  ScalarType count_type = ScalarType::kUint8;
};

struct PlyElement {
  std::string name;
  int64_t count = 0;
  std::vector<PlyProperty> properties;
  int64_t header_line = 0;
  int64_t count_column = 0;  // of the count on its header line
};

// Whitespace-separated tokens of an ascii body with their line and column.
struct AsciiToken {
  std::string_view text;
  int64_t line = 0;
  int64_t column = 0;
};

class PlyParser {
 public:
  PlyParser(const std::string& path, const std::string& bytes, const PointCloudReadOptions& options)
      : source_(path, bytes), options_(options) {}

  lidar::PointCloud Parse() {
    ParseHeader();
    const size_t vertex_index = FindVertexElement();
    ResolveVertexRoles(elements_[vertex_index]);
    lidar::PointCloud cloud;
    if (format_ == PlyFormat::kAscii) {
      // The body starts on the line after end_header.
      source_.set_line(source_.line() + 1);
      line_start_ = source_.pos();
      for (size_t e = 0; e < vertex_index; ++e) SkipAsciiElement(elements_[e]);
      cloud = ReadAsciiVertices(elements_[vertex_index]);
    } else {
      for (size_t e = 0; e < vertex_index; ++e) SkipBinaryElement(elements_[e]);
      cloud = ReadBinaryVertices(elements_[vertex_index]);
    }
    if (vertex_index + 1 == elements_.size()) ExpectEndOfBody(elements_[vertex_index]);
    return cloud;
  }

 private:
  ScalarType ParseType(const Word& word) const {
    const std::optional<ScalarType> type = PlyScalarType(std::string(word.text));
    if (!type) {
      source_.FailAtColumn(
          word.column,
          "unknown PLY property type " + Quote(word.text) +
              " (expected char, uchar, short, ushort, int, uint, float, double or int8, "
              "uint8, int16, uint16, int32, uint32, float32, float64)");
    }
    return *type;
  }

  void ParseFormat(const std::vector<Word>& words) {
    if (format_seen_) source_.FailAtColumn(1, "second 'format' line in the PLY header");
    if (words.size() != 3)
      source_.FailAtColumn(1,
                           "expected 'format <ascii|binary_little_endian|binary_big_endian> 1.0'");
    if (words[1].text == "ascii") {
      format_ = PlyFormat::kAscii;
    } else if (words[1].text == "binary_little_endian") {
      format_ = PlyFormat::kBinaryLittleEndian;
    } else if (words[1].text == "binary_big_endian") {
      format_ = PlyFormat::kBinaryBigEndian;
    } else {
      source_.FailAtColumn(words[1].column,
                           "unknown PLY format " + Quote(words[1].text) +
                               " (expected ascii, binary_little_endian or binary_big_endian)");
    }
    if (words[2].text != "1.0") {
      source_.FailAtColumn(words[2].column,
                           "unsupported PLY version " + Quote(words[2].text) + " (expected 1.0)");
    }
    format_seen_ = true;
  }

  void ParseElement(const std::vector<Word>& words) {
    if (words.size() != 3) source_.FailAtColumn(1, "expected 'element <name> <count>'");
    PlyElement element;
    element.name = std::string(words[1].text);
    element.header_line = source_.line();
    element.count = source_.IntegerAt(words[2].text, source_.line(), words[2].column);
    element.count_column = words[2].column;
    if (element.count < 0) source_.FailAtColumn(words[2].column, "negative element count");
    elements_.push_back(element);
  }

  void ParseProperty(const std::vector<Word>& words) {
    if (elements_.empty()) source_.FailAtColumn(1, "'property' before any 'element' line");
    PlyProperty property;
    if (words.size() >= 2 && words[1].text == "list") {
      if (words.size() != 5)
        source_.FailAtColumn(1, "expected 'property list <count type> <value type> <name>'");
      property.is_list = true;
      property.count_type = ParseType(words[2]);
      if (!IsIntegerType(property.count_type)) {
        source_.FailAtColumn(words[2].column, "a list count must have an integer type");
      }
      property.type = ParseType(words[3]);
      property.name = std::string(words[4].text);
    } else {
      if (words.size() != 3) source_.FailAtColumn(1, "expected 'property <type> <name>'");
      property.type = ParseType(words[1]);
      property.name = std::string(words[2].text);
    }
    elements_.back().properties.push_back(property);
  }

  void ParseHeader() {
    if (source_.size() == 0)
      source_.FailAtByte(0, "empty file; a PLY file starts with the line 'ply'");
    std::string_view line;
    source_.NextLine(&line);
    if (line != "ply") {
      source_.FailAt(1, 1, "not a PLY file: the first line must be 'ply', found " + Quote(line));
    }
    while (source_.NextLine(&line)) {
      const std::vector<Word> words = SplitWords(line);
      if (words.empty()) continue;
      const std::string_view keyword = words[0].text;
      if (keyword == "comment" || keyword == "obj_info") continue;
      if (keyword == "format") {
        ParseFormat(words);
      } else if (keyword == "element") {
        ParseElement(words);
      } else if (keyword == "property") {
        ParseProperty(words);
      } else if (keyword == "end_header") {
        if (!format_seen_) source_.FailAtColumn(1, "PLY header has no 'format' line");
        end_header_line_ = source_.line();
        CheckElementsHaveProperties();
        return;
      } else {
        source_.FailAtColumn(words[0].column, "unknown PLY header keyword " + Quote(keyword));
      }
    }
    source_.FailAtByte(source_.size(),
                       "file ends inside the PLY header (no 'end_header' line): truncated?");
  }

  // An instance without properties occupies no bytes, so a count could not be checked
  // against the file (and skipping 10^18 of them would take forever).
  void CheckElementsHaveProperties() const {
    for (const PlyElement& element : elements_) {
      if (element.properties.empty() && element.count > 0) {
        source_.FailAt(element.header_line, element.count_column,
                       "element '" + element.name + "' has no properties but a count of " +
                           std::to_string(element.count) + " (expected 0)");
      }
    }
  }

  size_t FindVertexElement() const {
    for (size_t e = 0; e < elements_.size(); ++e) {
      if (elements_[e].name == "vertex") return e;
    }
    source_.FailAt(end_header_line_, 1, "PLY header declares no 'vertex' element");
  }

  // Maps each vertex property to the PointValue it fills, or -1 to skip it.
  void ResolveVertexRoles(const PlyElement& vertex) {
    roles_.assign(vertex.properties.size(), -1);
    const auto find = [&](std::string_view name) -> int {
      for (size_t p = 0; p < vertex.properties.size(); ++p) {
        if (vertex.properties[p].name == name) return static_cast<int>(p);
      }
      return -1;
    };
    const char* const kAxes[] = {"x", "y", "z"};
    for (int axis = 0; axis < 3; ++axis) {
      const int p = find(kAxes[axis]);
      if (p < 0) {
        source_.FailAt(vertex.header_line, 1,
                       std::string("vertex element has no property '") + kAxes[axis] +
                           "'; a point cloud needs x, y and z");
      }
      if (vertex.properties[p].is_list) {
        source_.FailAt(vertex.header_line, 1,
                       std::string("vertex property '") + kAxes[axis] + "' is a list");
      }
      roles_[p] = axis;
    }
    // The property that fills `role`, or -1.
    const auto assign_optional = [&](int role, std::string_view first, std::string_view second) {
      int p = find(first);
      if (p < 0) p = find(second);
      if (p < 0 || vertex.properties[p].is_list) return -1;
      roles_[p] = role;
      return p;
    };
    has_intensity_ = assign_optional(kIntensity, "intensity", "scalar_intensity") >= 0;
    const int time = assign_optional(kTime, "t", "time");
    time_ = PointTimeOf(time >= 0, time >= 0 ? vertex.properties[time].type : ScalarType::kFloat32);
  }

  // The rest of the file must hold `element.count` instances of at least
  // `min_bytes_per_instance` bytes each (> 0 whenever count > 0, see
  // CheckElementsHaveProperties); this also bounds every loop over them by the file size.
  void CheckInstanceCount(const PlyElement& element, size_t min_bytes_per_instance) const {
    const size_t remaining = source_.remaining();
    if (element.count > 0 &&
        (min_bytes_per_instance == 0 ||
         static_cast<uint64_t>(element.count) > remaining / min_bytes_per_instance)) {
      source_.FailAtByte(source_.size(),
                         "file ends at byte " + std::to_string(source_.size()) +
                             " but the header (line " + std::to_string(element.header_line) +
                             ") declares " + std::to_string(element.count) + " " + element.name +
                             " instances needing at least " +
                             std::to_string(min_bytes_per_instance) + " bytes each after byte " +
                             std::to_string(source_.pos()) + ": truncated?");
    }
  }

  void AddPoint(PointCloudBuilder* builder, const double (&values)[kNumPointValues], int64_t index,
                int64_t line, size_t byte_offset) const {
    int bad = 0;
    const PointCloudBuilder::AddResult result = builder->Add(values, &bad);
    FailOnRefusedPoint(
        result, "vertex", index, bad, values, time_,
        [&](const std::string& message) { source_.FailAtLineOrByte(line, byte_offset, message); });
  }

  // After the last element nothing may follow but blanks (ascii): more points than the header
  // declares (a writer that never updated its count) would otherwise be dropped silently.
  void ExpectEndOfBody(const PlyElement& last) {
    const std::string message = "data after the " + std::to_string(last.count) + " " + last.name +
                                " instances the header declares (element " + last.name + " " +
                                std::to_string(last.count) + ")";
    if (format_ != PlyFormat::kAscii) {
      if (source_.remaining() > 0) {
        source_.FailAtByte(source_.pos(),
                           std::to_string(source_.remaining()) + " bytes of " + message);
      }
      return;
    }
    AsciiToken token;
    if (NextToken(&token)) source_.FailAt(token.line, token.column, message);
  }

  // ---- ascii body ----

  bool NextToken(AsciiToken* token) {
    const std::string& bytes = source_.bytes();
    size_t pos = source_.pos();
    int64_t line = source_.line();
    while (pos < bytes.size()) {
      const char c = bytes[pos];
      if (c == '\n') {
        ++line;
        line_start_ = pos + 1;
      } else if (c != ' ' && c != '\t' && c != '\r') {
        break;
      }
      ++pos;
    }
    source_.set_line(line);
    const size_t start = pos;
    while (pos < bytes.size() && bytes[pos] != ' ' && bytes[pos] != '\t' && bytes[pos] != '\r' &&
           bytes[pos] != '\n') {
      ++pos;
    }
    source_.set_pos(pos);
    if (pos == start) return false;
    token->text = std::string_view(bytes).substr(start, pos - start);
    token->line = line;
    token->column = static_cast<int64_t>(start - line_start_) + 1;
    return true;
  }

  // Reads the next value of instance `index` of `element`, which must be on `line`.
  AsciiToken AsciiValue(const PlyElement& element, int64_t index, int64_t line) {
    AsciiToken token;
    const int64_t end_column = static_cast<int64_t>(source_.pos() - line_start_) + 1;
    if (!NextToken(&token)) {
      source_.FailAtByte(source_.size(), "file ends inside " + element.name + " " +
                                             std::to_string(index) + " of " +
                                             std::to_string(element.count) + " (line " +
                                             std::to_string(source_.line()) + "): truncated?");
    }
    if (line > 0 && token.line != line) {
      source_.FailAt(line, end_column,
                     element.name + " line has fewer values than the header declares (" +
                         std::to_string(element.properties.size()) + " properties)");
    }
    return token;
  }

  void ExpectEndOfAsciiLine(const PlyElement& element) {
    const std::string& bytes = source_.bytes();
    size_t pos = source_.pos();
    while (pos < bytes.size() && (bytes[pos] == ' ' || bytes[pos] == '\t' || bytes[pos] == '\r')) {
      ++pos;
    }
    source_.set_pos(pos);
    if (pos < bytes.size() && bytes[pos] != '\n') {
      source_.FailAtColumn(static_cast<int64_t>(pos - line_start_) + 1,
                           element.name + " line has more values than the header declares (" +
                               std::to_string(element.properties.size()) + " properties)");
    }
  }

  int64_t AsciiListCount(const AsciiToken& token) const {
    const int64_t count = source_.IntegerAt(token.text, token.line, token.column);
    if (count < 0) source_.FailAt(token.line, token.column, "negative list length");
    return count;
  }

  void SkipAsciiElement(const PlyElement& element) {
    // Each value takes at least one character.
    CheckInstanceCount(element, element.properties.size());
    for (int64_t i = 0; i < element.count; ++i) {
      int64_t line = 0;
      for (const PlyProperty& property : element.properties) {
        const AsciiToken first = AsciiValue(element, i, line);
        line = first.line;
        const int64_t n = property.is_list ? AsciiListCount(first) : 0;
        for (int64_t k = 0; k < n; ++k) AsciiValue(element, i, line);
      }
      ExpectEndOfAsciiLine(element);
    }
  }

  lidar::PointCloud ReadAsciiVertices(const PlyElement& vertex) {
    CheckInstanceCount(vertex, vertex.properties.size());
    PointCloudBuilder builder(vertex.count, has_intensity_, time_, options_.drop_non_finite_points);
    for (int64_t i = 0; i < vertex.count; ++i) {
      double values[kNumPointValues] = {0.0, 0.0, 0.0, 0.0, 0.0};
      int64_t line = 0;
      for (size_t p = 0; p < vertex.properties.size(); ++p) {
        const AsciiToken token = AsciiValue(vertex, i, line);
        line = token.line;
        if (vertex.properties[p].is_list) {
          const int64_t n = AsciiListCount(token);
          for (int64_t k = 0; k < n; ++k) AsciiValue(vertex, i, line);
          continue;
        }
        if (roles_[p] < 0) continue;
        values[roles_[p]] = source_.DoubleAt(token.text, token.line, token.column);
      }
      ExpectEndOfAsciiLine(vertex);
      AddPoint(&builder, values, i, line, 0);
    }
    return builder.Finish();
  }

  // ---- binary body ----

  bool LittleEndian() const { return format_ == PlyFormat::kBinaryLittleEndian; }

  void NeedBytes(size_t n, const PlyElement& element, int64_t index) const {
    if (n > source_.remaining()) {
      source_.FailAtByte(source_.size(), "file ends at byte " + std::to_string(source_.size()) +
                                             " inside " + element.name + " " +
                                             std::to_string(index) + " of " +
                                             std::to_string(element.count) + ": truncated?");
    }
  }

  double BinaryValue(ScalarType type, const PlyElement& element, int64_t index) {
    NeedBytes(ScalarSize(type), element, index);
    const double value = DecodeScalar(source_.bytes().data() + source_.pos(), type, LittleEndian());
    source_.Advance(ScalarSize(type));
    return value;
  }

  void SkipBinaryList(const PlyProperty& property, const PlyElement& element, int64_t index) {
    const size_t count_offset = source_.pos();
    const double count = BinaryValue(property.count_type, element, index);
    if (count < 0)
      source_.FailAtByte(count_offset,
                         "negative list length in " + element.name + " " + std::to_string(index));
    // count < 2^32 (an integer count type), so this cannot overflow; checked all the same.
    size_t bytes = 0;
    if (!CheckedMultiply(static_cast<size_t>(count), ScalarSize(property.type), &bytes)) {
      source_.FailAtByte(count_offset, "list length " + FormatDouble(count) + " in " +
                                           element.name + " " + std::to_string(index) +
                                           " overflows");
    }
    NeedBytes(bytes, element, index);
    source_.Advance(bytes);
  }

  size_t MinBinarySize(const PlyElement& element) const {
    size_t size = 0;
    for (const PlyProperty& property : element.properties) {
      size += ScalarSize(property.is_list ? property.count_type : property.type);
    }
    return size;
  }

  void SkipBinaryElement(const PlyElement& element) {
    CheckInstanceCount(element, MinBinarySize(element));
    for (int64_t i = 0; i < element.count; ++i) {
      for (const PlyProperty& property : element.properties) {
        if (property.is_list) {
          SkipBinaryList(property, element, i);
        } else {
          NeedBytes(ScalarSize(property.type), element, i);
          source_.Advance(ScalarSize(property.type));
        }
      }
    }
  }

  lidar::PointCloud ReadBinaryVertices(const PlyElement& vertex) {
    const size_t record_size = MinBinarySize(vertex);
    CheckInstanceCount(vertex, record_size);
    PointCloudBuilder builder(vertex.count, has_intensity_, time_, options_.drop_non_finite_points);
    const bool fixed_size =
        std::none_of(vertex.properties.begin(), vertex.properties.end(),
                     [](const PlyProperty& property) { return property.is_list; });
    if (fixed_size) {
      // Records of one size, all present (CheckPointCount): each value is decoded at its
      // offset in the record, without a bounds check per value.
      struct Field {
        size_t offset;
        ScalarType type;
        int role;
      };
      std::vector<Field> fields;
      size_t offset = 0;
      for (size_t p = 0; p < vertex.properties.size(); ++p) {
        const PlyProperty& property = vertex.properties[p];
        if (roles_[p] >= 0) fields.push_back({offset, property.type, roles_[p]});
        offset += ScalarSize(property.type);
      }
      const size_t begin = source_.pos();
      const char* data = source_.bytes().data() + begin;
      for (int64_t i = 0; i < vertex.count; ++i) {
        const size_t record = static_cast<size_t>(i) * record_size;
        double values[kNumPointValues] = {0.0, 0.0, 0.0, 0.0, 0.0};
        for (const Field& field : fields) {
          values[field.role] =
              DecodeScalar(data + record + field.offset, field.type, LittleEndian());
        }
        AddPoint(&builder, values, i, 0, begin + record);
      }
      source_.Advance(static_cast<size_t>(vertex.count) * record_size);
      return builder.Finish();
    }
    for (int64_t i = 0; i < vertex.count; ++i) {
      const size_t vertex_offset = source_.pos();
      double values[kNumPointValues] = {0.0, 0.0, 0.0, 0.0, 0.0};
      for (size_t p = 0; p < vertex.properties.size(); ++p) {
        const PlyProperty& property = vertex.properties[p];
        if (property.is_list) {
          SkipBinaryList(property, vertex, i);
        } else if (roles_[p] >= 0) {
          values[roles_[p]] = BinaryValue(property.type, vertex, i);
        } else {
          NeedBytes(ScalarSize(property.type), vertex, i);
          source_.Advance(ScalarSize(property.type));
        }
      }
      AddPoint(&builder, values, i, 0, vertex_offset);
    }
    return builder.Finish();
  }

  ByteSource source_;
  const PointCloudReadOptions& options_;
  size_t line_start_ = 0;
  int64_t end_header_line_ = 0;
  bool format_seen_ = false;
  PlyFormat format_ = PlyFormat::kAscii;
  std::vector<PlyElement> elements_;
  std::vector<int> roles_;
  bool has_intensity_ = false;
  PointTime time_ = PointTime::kNone;
};

}  // namespace

lidar::PointCloud ParsePly(const std::string& path, const std::string& bytes,
                           const PointCloudReadOptions& options) {
  return PlyParser(path, bytes, options).Parse();
}

}  // namespace internal
}  // namespace io
}  // namespace autocal
