// The message decoders on messages serialized by test/import/ros_message_writer.h, in both
// ROS 1 and CDR form, and their refusals (short messages, bad CDR headers, PointCloud2
// sizes that disagree).

#include "import/ros_messages.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>

#include "autocal/common/error.h"
#include "import/ros_message_writer.h"

namespace autocal {
namespace import {
namespace {

using test::AppendValue;
using test::RosMessageWriter;
using test::TestPointField;
using ::testing::HasSubstr;

constexpr int64_t kStampNs = 1700000000123456789;

class MessagesTest : public ::testing::TestWithParam<bool> {
 protected:
  bool cdr() const { return GetParam(); }
  Serialization serialization() const { return cdr() ? Serialization::kCdr : Serialization::kRos1; }
  MessageCursor Cursor(const std::string& bytes) {
    context_.location = {"x.bag", 0, 0, 4242};
    context_.type = "sensor_msgs/Test";
    context_.topic = "/test";
    return MessageCursor(bytes, serialization(), &context_);
  }
  MessageContext context_;
};

INSTANTIATE_TEST_SUITE_P(Serializations, MessagesTest, ::testing::Values(false, true),
                         [](const auto& info) { return info.param ? "Cdr" : "Ros1"; });

TEST_P(MessagesTest, CursorReadsPrimitivesStringsAndAlignment) {
  RosMessageWriter w(cdr());
  w.U8(3).F64(2.5).String("abc").U16(9).I32(-4).String("").F32(1.5f);
  MessageCursor cursor = Cursor(w.bytes());
  EXPECT_EQ(cursor.U8(), 3);
  EXPECT_EQ(cursor.F64(), 2.5);  // CDR: 7 bytes of padding before it
  EXPECT_EQ(cursor.String(), "abc");
  EXPECT_EQ(cursor.U16(), 9);
  EXPECT_EQ(cursor.I32(), -4);
  EXPECT_EQ(cursor.String(), "");
  EXPECT_EQ(cursor.F32(), 1.5f);
  EXPECT_EQ(cursor.remaining(), 0u);
}

TEST_P(MessagesTest, CursorNamesBagOffsetTypeAndByteWhenShort) {
  RosMessageWriter w(cdr());
  w.U32(5);
  MessageCursor cursor = Cursor(w.bytes());
  cursor.U32();
  try {
    cursor.F64();
    FAIL() << "read past the end";
  } catch (const ParseError& e) {
    EXPECT_THAT(e.what(), HasSubstr("x.bag: byte 4242"));
    EXPECT_THAT(e.what(), HasSubstr("sensor_msgs/Test message on /test"));
    EXPECT_THAT(e.what(), HasSubstr("message too short for its type"));
    EXPECT_THAT(e.what(), HasSubstr("float64"));
  }
}

TEST_P(MessagesTest, SequenceCountBeyondTheMessageIsRefused) {
  RosMessageWriter w(cdr());
  w.U32(1000000).F64(1.0);
  MessageCursor cursor = Cursor(w.bytes());
  EXPECT_THROW(cursor.SequenceCount(8), ParseError);
}

TEST(MessageCursorTest, CdrRefusesBigEndianAndStringsWithoutNul) {
  MessageContext context;
  context.type = "sensor_msgs/Imu";
  EXPECT_THROW(MessageCursor(std::string("\x00\x00\x00\x00", 4), Serialization::kCdr, &context),
               ParseError);
  EXPECT_THROW(MessageCursor(std::string("\x00", 1), Serialization::kCdr, &context), ParseError);
  std::string bytes("\x00\x01\x00\x00", 4);
  bytes += std::string(
      "\x02\x00\x00\x00"
      "ab",
      6);  // count 2, no NUL
  MessageCursor cursor(bytes, Serialization::kCdr, &context);
  EXPECT_THROW(cursor.String(), ParseError);
}

TEST_P(MessagesTest, Imu) {
  const std::string bytes =
      test::SerializeImu(cdr(), kStampNs, "imu_link", {0.1, -0.2, 0.3}, {0.5, 9.8, -0.1});
  MessageCursor cursor = Cursor(bytes);
  const ImuMessage imu = DecodeImu(&cursor);
  EXPECT_EQ(imu.stamp_ns, kStampNs);
  EXPECT_EQ(imu.frame_id, "imu_link");
  EXPECT_EQ(imu.angular_velocity_rad_s, Eigen::Vector3d(0.1, -0.2, 0.3));
  EXPECT_EQ(imu.linear_acceleration_m_s2, Eigen::Vector3d(0.5, 9.8, -0.1));
  EXPECT_EQ(cursor.remaining(), 0u);
}

TEST_P(MessagesTest, ImuShorterThanItsTypeIsRefused) {
  std::string bytes =
      test::SerializeImu(cdr(), kStampNs, "imu_link", {0.1, -0.2, 0.3}, {0.5, 9.8, -0.1});
  bytes.resize(bytes.size() - 20);
  MessageCursor cursor = Cursor(bytes);
  EXPECT_THROW(DecodeImu(&cursor), ParseError);
}

TEST_P(MessagesTest, OdometryAndTwistStamped) {
  const std::string odometry = test::SerializeOdometry(cdr(), kStampNs, 1.25, -0.5);
  MessageCursor cursor = Cursor(odometry);
  const VehicleTwistMessage a = DecodeOdometry(&cursor);
  EXPECT_EQ(a.stamp_ns, kStampNs);
  EXPECT_EQ(a.frame_id, "base_link");
  EXPECT_EQ(a.speed_m_s, 1.25);
  EXPECT_EQ(a.yaw_rate_rad_s, -0.5);
  EXPECT_EQ(cursor.remaining(), 0u);

  const std::string twist = test::SerializeTwistStamped(cdr(), kStampNs, 3.0, 0.25);
  MessageCursor cursor2 = Cursor(twist);
  const VehicleTwistMessage b = DecodeTwistStamped(&cursor2);
  EXPECT_EQ(b.speed_m_s, 3.0);
  EXPECT_EQ(b.yaw_rate_rad_s, 0.25);
  EXPECT_EQ(cursor2.remaining(), 0u);
}

TEST_P(MessagesTest, JointState) {
  const std::string bytes = test::SerializeJointState(
      cdr(), kStampNs, {"rear_left_wheel", "rear_right_wheel"}, {1.0, 2.0}, {3.5, 4.5});
  MessageCursor cursor = Cursor(bytes);
  const JointStateMessage joints = DecodeJointState(&cursor);
  EXPECT_THAT(joints.names, ::testing::ElementsAre("rear_left_wheel", "rear_right_wheel"));
  EXPECT_THAT(joints.position_rad, ::testing::ElementsAre(1.0, 2.0));
  EXPECT_THAT(joints.velocity_rad_s, ::testing::ElementsAre(3.5, 4.5));
  EXPECT_EQ(cursor.remaining(), 0u);
}

TEST_P(MessagesTest, NavSatFix) {
  const std::string bytes =
      test::SerializeNavSatFix(cdr(), kStampNs, -1, 48.1, 11.5, 520.25, {4, 9, 16}, 2);
  MessageCursor cursor = Cursor(bytes);
  const NavSatFixMessage fix = DecodeNavSatFix(&cursor);
  EXPECT_EQ(fix.status, -1);
  EXPECT_EQ(fix.latitude_deg, 48.1);
  EXPECT_EQ(fix.longitude_deg, 11.5);
  EXPECT_EQ(fix.altitude_m, 520.25);
  EXPECT_EQ(fix.position_covariance_m2[0], 4);
  EXPECT_EQ(fix.position_covariance_m2[4], 9);
  EXPECT_EQ(fix.position_covariance_m2[8], 16);
  EXPECT_EQ(fix.covariance_type, 2);
  EXPECT_EQ(cursor.remaining(), 0u);
}

TEST_P(MessagesTest, TfMessage) {
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  const std::string bytes = test::SerializeTfMessage(
      cdr(), kStampNs,
      {{"base_link", "imu_link", q, {0.1, 0.2, 0.3}},
       {"/base_link", "velodyne", Eigen::Quaterniond::Identity(), {1, 0, 2}}});
  MessageCursor cursor = Cursor(bytes);
  const std::vector<StampedTransform> transforms = DecodeTfMessage(&cursor);
  ASSERT_EQ(transforms.size(), 2u);
  EXPECT_EQ(transforms[0].parent_frame, "base_link");
  EXPECT_EQ(transforms[0].child_frame, "imu_link");
  EXPECT_TRUE(transforms[0].T_parent_child.q.isApprox(q, 1e-15));
  EXPECT_EQ(transforms[0].T_parent_child.p, Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_EQ(transforms[1].parent_frame, "/base_link");
  EXPECT_EQ(cursor.remaining(), 0u);
}

// Four points; the time field (if any) in the given form; the third point has no return.
struct CloudCase {
  const char* name;
  const char* time_field;  // "" for none
  uint8_t datatype;
  PointTimeForm form;
};

std::string TimeBytes(const CloudCase& c, int i) {
  std::string out;
  const double relative_s = 0.025 * i;
  switch (c.form) {
    case PointTimeForm::kRelativeNsU32:
    case PointTimeForm::kOffsetNsU32:
      AppendValue<uint32_t>(&out, static_cast<uint32_t>(relative_s * 1e9 + 0.5));
      break;
    case PointTimeForm::kRelativeSecondsF32:
      AppendValue<float>(&out, static_cast<float>(relative_s));
      break;
    case PointTimeForm::kAbsoluteSecondsF64:
      AppendValue<double>(&out, static_cast<double>(kStampNs / 1000000000) +
                                    static_cast<double>(kStampNs % 1000000000) * 1e-9 + relative_s);
      break;
    case PointTimeForm::kNone:
      break;
  }
  return out;
}

TEST_P(MessagesTest, PointCloud2InEveryTimeForm) {
  const CloudCase cases[] = {
      {"t", "t", 6, PointTimeForm::kRelativeNsU32},
      {"time", "time", 7, PointTimeForm::kRelativeSecondsF32},
      {"timestamp", "timestamp", 8, PointTimeForm::kAbsoluteSecondsF64},
      {"offset_time", "offset_time", 6, PointTimeForm::kOffsetNsU32},
      {"none", "", 0, PointTimeForm::kNone},
  };
  for (const CloudCase& c : cases) {
    SCOPED_TRACE(c.name);
    std::vector<TestPointField> fields = {
        {"x", 0, 7}, {"y", 4, 7}, {"z", 8, 7}, {"intensity", 16, 7}};
    const uint32_t time_bytes = c.form == PointTimeForm::kAbsoluteSecondsF64 ? 8 : 4;
    if (c.form != PointTimeForm::kNone) fields.push_back({c.time_field, 20, c.datatype});
    const uint32_t point_step = 20 + (c.form == PointTimeForm::kNone ? 0 : time_bytes) + 4;
    std::string data;
    for (int i = 0; i < 4; ++i) {
      const float v = i == 2 ? 0.0f : 1.0f + i;
      AppendValue<float>(&data, v);
      AppendValue<float>(&data, -v);
      AppendValue<float>(&data, 0.5f * v);
      AppendValue<float>(&data, 0.0f);  // padding between z and intensity
      AppendValue<float>(&data, 10.0f * i);
      data += TimeBytes(c, i);
      data.append(4, '\0');  // trailing padding
    }
    const std::string bytes = test::SerializePointCloud2(cdr(), kStampNs, "velodyne", 1, 4, fields,
                                                         point_step, point_step * 4, data);
    MessageCursor cursor = Cursor(bytes);
    const PointCloudMessage cloud = DecodePointCloud2(&cursor);
    EXPECT_EQ(cursor.remaining(), 0u);
    EXPECT_EQ(cloud.time_form, c.form);
    EXPECT_EQ(cloud.frame_id, "velodyne");
    ASSERT_EQ(cloud.cloud.size(), 3);
    EXPECT_EQ(cloud.dropped_points, 1);
    ASSERT_TRUE(cloud.cloud.has_intensity());
    ASSERT_TRUE(cloud.cloud.has_time());
    const int kept[] = {0, 1, 3};
    for (int k = 0; k < 3; ++k) {
      const int i = kept[k];
      EXPECT_EQ(cloud.cloud.points.col(k), Eigen::Vector3d(1.0 + i, -(1.0 + i), 0.5 * (1.0 + i)));
      EXPECT_EQ(cloud.cloud.intensity[k], 10.0f * i);
      const double expected_t = c.form == PointTimeForm::kNone ? 0.0 : 0.025 * i;
      EXPECT_NEAR(cloud.cloud.time_s[k], expected_t, 2e-7) << "point " << i;
    }
  }
}

// Regression (fuzz_ros_messages): a cloud of width 0 and height 2^32 - 1 holds no points but
// made the decoder walk every one of its empty rows (a minute under the fuzzer). An optimizing
// build removes that empty loop, so the time bound catches it only in unoptimized and
// sanitizer builds.
TEST_P(MessagesTest, PointCloud2OfWidthZeroIsEmptyWhateverItsHeight) {
  const std::vector<TestPointField> fields = {{"x", 0, 7}, {"y", 4, 7}, {"z", 8, 7}};
  const std::string bytes =
      test::SerializePointCloud2(cdr(), kStampNs, "l", 0xffffffffu, 0, fields, 12, 0, "");
  MessageCursor cursor = Cursor(bytes);
  const auto start = std::chrono::steady_clock::now();
  const PointCloudMessage cloud = DecodePointCloud2(&cursor);
  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(cloud.height, 0xffffffffu);
  EXPECT_EQ(cloud.cloud.points.cols(), 0);
  EXPECT_EQ(cloud.dropped_points, 0);
  EXPECT_LT(elapsed_s, 0.1);
}

TEST_P(MessagesTest, PointCloud2WithDisagreeingSizesIsRefused) {
  const std::vector<TestPointField> fields = {{"x", 0, 7}, {"y", 4, 7}, {"z", 8, 7}};
  const std::string data(12 * 4, '\0');
  struct Case {
    const char* name;
    uint32_t width, point_step, row_step;
    const char* expected;
  };
  const Case cases[] = {
      {"data shorter than row_step * height", 5, 12, 60, "sizes disagree"},
      {"row_step below width * point_step", 4, 12, 40, "sizes disagree"},
      {"field beyond point_step", 6, 8, 48, "does not fit in point_step"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string bytes = test::SerializePointCloud2(cdr(), kStampNs, "l", 1, c.width, fields,
                                                         c.point_step, c.row_step, data);
    MessageCursor cursor = Cursor(bytes);
    try {
      DecodePointCloud2(&cursor);
      FAIL() << "accepted";
    } catch (const ParseError& e) {
      EXPECT_THAT(e.what(), HasSubstr(c.expected));
      EXPECT_THAT(e.what(), HasSubstr("x.bag: byte 4242"));
    }
  }
}

// Every message cut short anywhere is refused with a ParseError: the decoders read every
// field, so no prefix of a message is a message.
TEST_P(MessagesTest, EveryTruncationIsRefused) {
  const std::vector<test::TestPointField> fields = {{"x", 0, 7}, {"y", 4, 7}, {"z", 8, 7}};
  const std::pair<std::string, void (*)(MessageCursor*)> messages[] = {
      {test::SerializeImu(cdr(), kStampNs, "imu", {1, 2, 3}, {4, 5, 6}),
       [](MessageCursor* c) { DecodeImu(c); }},
      {test::SerializeOdometry(cdr(), kStampNs, 1, 2), [](MessageCursor* c) { DecodeOdometry(c); }},
      {test::SerializeTwistStamped(cdr(), kStampNs, 1, 2),
       [](MessageCursor* c) { DecodeTwistStamped(c); }},
      {test::SerializeJointState(cdr(), kStampNs, {"l", "r"}, {1, 2}, {3, 4}),
       [](MessageCursor* c) { DecodeJointState(c); }},
      {test::SerializeNavSatFix(cdr(), kStampNs, 0, 1, 2, 3, {1, 1, 1}, 2),
       [](MessageCursor* c) { DecodeNavSatFix(c); }},
      {test::SerializeTfMessage(cdr(), kStampNs,
                                {{"a", "b", Eigen::Quaterniond::Identity(), {1, 2, 3}}}),
       [](MessageCursor* c) { DecodeTfMessage(c); }},
      {test::SerializePointCloud2(cdr(), kStampNs, "l", 1, 2, fields, 12, 24,
                                  std::string(24, '\x01')),
       [](MessageCursor* c) { DecodePointCloud2(c); }},
  };
  for (const auto& [bytes, decode] : messages) {
    MessageCursor whole = Cursor(bytes);
    EXPECT_NO_THROW(decode(&whole));
    for (size_t length = 0; length < bytes.size(); ++length) {
      try {
        const std::string prefix = bytes.substr(0, length);
        MessageCursor cursor = Cursor(prefix);
        decode(&cursor);
        ADD_FAILURE() << "a " << length << "-byte prefix of a " << bytes.size()
                      << "-byte message was accepted";
      } catch (const ParseError&) {
      }
    }
  }
}

TEST(MessageKindTest, RosOneAndRosTwoTypeNames) {
  EXPECT_EQ(KindOfType("sensor_msgs/Imu"), MessageKind::kImu);
  EXPECT_EQ(KindOfType("sensor_msgs/msg/Imu"), MessageKind::kImu);
  EXPECT_EQ(KindOfType("sensor_msgs/msg/PointCloud2"), MessageKind::kPointCloud2);
  EXPECT_EQ(KindOfType("tf2_msgs/msg/TFMessage"), MessageKind::kTfMessage);
  EXPECT_EQ(KindOfType("std_msgs/String"), MessageKind::kOther);
}

}  // namespace
}  // namespace import
}  // namespace autocal
