#pragma once

// Serializes the ROS messages autocal imports, in ROS 1 form (packed little-endian,
// strings without NUL, Header with seq) or in CDR form (encapsulation header 00 01 00 00,
// primitives aligned to their size after it, strings with NUL, Header without seq), for
// tests and benchmarks. Written from the message definitions, independently of the
// decoders under test.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace autocal {
namespace test {

class RosMessageWriter {
 public:
  explicit RosMessageWriter(bool cdr) : cdr_(cdr) {
    if (cdr_) out_ = std::string("\x00\x01\x00\x00", 4);
  }

  template <typename T>
  RosMessageWriter& Put(T value) {
    Align(sizeof(T));
    out_.append(reinterpret_cast<const char*>(&value), sizeof(T));
    return *this;
  }
  RosMessageWriter& U8(uint8_t v) { return Put(v); }
  RosMessageWriter& I8(int8_t v) { return Put(v); }
  RosMessageWriter& U16(uint16_t v) { return Put(v); }
  RosMessageWriter& U32(uint32_t v) { return Put(v); }
  RosMessageWriter& I32(int32_t v) { return Put(v); }
  RosMessageWriter& F32(float v) { return Put(v); }
  RosMessageWriter& F64(double v) { return Put(v); }
  RosMessageWriter& String(const std::string& s) {
    U32(static_cast<uint32_t>(s.size() + (cdr_ ? 1 : 0)));
    out_ += s;
    if (cdr_) out_.push_back('\0');
    return *this;
  }
  RosMessageWriter& Bytes(const std::string& bytes) {
    U32(static_cast<uint32_t>(bytes.size()));
    out_ += bytes;
    return *this;
  }
  RosMessageWriter& Header(int64_t stamp_ns, const std::string& frame_id, uint32_t seq = 7) {
    if (!cdr_) U32(seq);
    if (cdr_) {
      I32(static_cast<int32_t>(stamp_ns / 1000000000));
    } else {
      U32(static_cast<uint32_t>(stamp_ns / 1000000000));
    }
    U32(static_cast<uint32_t>(stamp_ns % 1000000000));
    return String(frame_id);
  }
  RosMessageWriter& Vector3(const Eigen::Vector3d& v) { return F64(v.x()).F64(v.y()).F64(v.z()); }
  RosMessageWriter& Quaternion(const Eigen::Quaterniond& q) {
    return F64(q.x()).F64(q.y()).F64(q.z()).F64(q.w());
  }
  RosMessageWriter& Zeros(int count) {
    for (int i = 0; i < count; ++i) F64(0.0);
    return *this;
  }

  const std::string& bytes() const { return out_; }

 private:
  void Align(size_t size) {
    if (!cdr_) return;
    while ((out_.size() - 4) % size != 0) out_.push_back('\0');
  }
  bool cdr_;
  std::string out_;
};

inline std::string SerializeImu(bool cdr, int64_t stamp_ns, const std::string& frame,
                                const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel) {
  RosMessageWriter w(cdr);
  w.Header(stamp_ns, frame).Quaternion(Eigen::Quaterniond::Identity()).Zeros(9);
  w.Vector3(gyro).Zeros(9).Vector3(accel).Zeros(9);
  return w.bytes();
}

inline std::string SerializeOdometry(bool cdr, int64_t stamp_ns, double speed, double yaw_rate) {
  RosMessageWriter w(cdr);
  w.Header(stamp_ns, "odom").String("base_link");
  w.Vector3({1, 2, 3}).Quaternion(Eigen::Quaterniond::Identity()).Zeros(36);
  w.Vector3({speed, 0.01, 0}).Vector3({0.02, 0.03, yaw_rate}).Zeros(36);
  return w.bytes();
}

inline std::string SerializeTwistStamped(bool cdr, int64_t stamp_ns, double speed,
                                         double yaw_rate) {
  RosMessageWriter w(cdr);
  w.Header(stamp_ns, "base_link").Vector3({speed, 0, 0}).Vector3({0, 0, yaw_rate});
  return w.bytes();
}

inline std::string SerializeJointState(bool cdr, int64_t stamp_ns,
                                       const std::vector<std::string>& names,
                                       const std::vector<double>& position,
                                       const std::vector<double>& velocity) {
  RosMessageWriter w(cdr);
  w.Header(stamp_ns, "");
  w.U32(static_cast<uint32_t>(names.size()));
  for (const std::string& name : names) w.String(name);
  for (const auto* values : {&position, &velocity}) {
    w.U32(static_cast<uint32_t>(values->size()));
    for (double v : *values) w.F64(v);
  }
  w.U32(0);  // effort
  return w.bytes();
}

inline std::string SerializeNavSatFix(bool cdr, int64_t stamp_ns, int8_t status, double lat,
                                      double lon, double alt, const Eigen::Vector3d& variance,
                                      uint8_t covariance_type) {
  RosMessageWriter w(cdr);
  w.Header(stamp_ns, "gps").I8(status).U16(1).F64(lat).F64(lon).F64(alt);
  const double c[9] = {variance.x(), 0.1, 0, 0.1, variance.y(), 0, 0, 0, variance.z()};
  for (double v : c) w.F64(v);
  w.U8(covariance_type);
  return w.bytes();
}

struct TestTransform {
  std::string parent, child;
  Eigen::Quaterniond q;
  Eigen::Vector3d p;
};

inline std::string SerializeTfMessage(bool cdr, int64_t stamp_ns,
                                      const std::vector<TestTransform>& transforms) {
  RosMessageWriter w(cdr);
  w.U32(static_cast<uint32_t>(transforms.size()));
  for (const TestTransform& t : transforms) {
    w.Header(stamp_ns, t.parent).String(t.child).Vector3(t.p).Quaternion(t.q);
  }
  return w.bytes();
}

// A PointCloud2 field: name, offset, datatype (7 float32, 8 float64, 6 uint32, ...).
struct TestPointField {
  std::string name;
  uint32_t offset;
  uint8_t datatype;
};

// A cloud of `points` rows of `point_step` bytes each (already laid out by the caller).
inline std::string SerializePointCloud2(bool cdr, int64_t stamp_ns, const std::string& frame,
                                        uint32_t height, uint32_t width,
                                        const std::vector<TestPointField>& fields,
                                        uint32_t point_step, uint32_t row_step,
                                        const std::string& data) {
  RosMessageWriter w(cdr);
  w.Header(stamp_ns, frame).U32(height).U32(width);
  w.U32(static_cast<uint32_t>(fields.size()));
  for (const TestPointField& f : fields) w.String(f.name).U32(f.offset).U8(f.datatype).U32(1);
  w.U8(0).U32(point_step).U32(row_step).Bytes(data).U8(1);
  return w.bytes();
}

// Appends `value` to a point's bytes.
template <typename T>
void AppendValue(std::string* data, T value) {
  data->append(reinterpret_cast<const char*>(&value), sizeof(T));
}

}  // namespace test
}  // namespace autocal
