// import::ImportBag end to end on ROS 1 bags written by the test writers: every stream
// lands in the dataset that io::ReadDataset reads back, /tf_static gives the nominal
// extrinsics, and the output directory is never left half-written.

#include "autocal/import/import_bag.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/io/dataset.h"
#include "import/ros1_bag_writer.h"
#include "import/ros_message_writer.h"
#include "support/test_paths.h"

namespace autocal {
namespace import {
namespace {

namespace fs = std::filesystem;
using test::AppendValue;
using test::Ros1BagWriter;
using ::testing::HasSubstr;

constexpr int64_t kStartNs = 1700000000000000000;
constexpr int64_t kHeaderLagNs = 2000000;  // header stamps lead the receive times by 2 ms

// The static transforms of the rig: base_link -> imu_link, velodyne, gps.
const Eigen::Quaterniond kQBaseImu(Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitZ()) *
                                   Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
const Eigen::Vector3d kPBaseImu(0.0, -0.3, 0.52);
const Eigen::Quaterniond kQBaseLidar(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()));
const Eigen::Vector3d kPBaseLidar(0.8, 0.0, 1.2);
const Eigen::Vector3d kPBaseGps(-0.2, 0.1, 1.5);

std::string Cloud(int64_t stamp_ns, int sweep) {
  const std::vector<test::TestPointField> fields = {
      {"x", 0, 7}, {"y", 4, 7}, {"z", 8, 7}, {"intensity", 12, 7}, {"time", 16, 7}};
  std::string data;
  for (int i = 0; i < 100; ++i) {
    AppendValue<float>(&data, 5.0f + 0.01f * i);
    AppendValue<float>(&data, 0.1f * sweep);
    AppendValue<float>(&data, -1.0f);
    AppendValue<float>(&data, static_cast<float>(i));
    AppendValue<float>(&data, 0.001f * i);
  }
  return test::SerializePointCloud2(false, stamp_ns, "velodyne", 1, 100, fields, 20, 2000, data);
}

struct RigOptions {
  bool second_imu = false;
  bool corrupt_imu = false;
  uint8_t gnss_covariance_type = 2;
  bool gnss_altitude_nan = false;  // as nmea_navsat_driver publishes its RMC fixes
  bool joint_velocities = true;
  bool repeated_joint_stamp = false;  // the JointState at 0.2 s stamped as the one before it
  double gyro_scale = 1.0;            // 57.3: a driver that publishes deg/s
  // NaN in the IMU message at 0.5 s, the odometry at 0.2 s and the rear wheels' velocities at
  // 0.4 s (a driver that does not know them; their angles stay finite).
  bool non_finite_values = false;
  bool two_fixes_300_s_apart = false;  // every other fix without a fix; one lone sweep
  std::vector<std::string> joints = {"front_left_wheel", "front_right_wheel", "rear_left_wheel",
                                     "rear_right_wheel"};
};

// 2 s of a rig: IMU 200 Hz, LiDAR 10 Hz, wheels 50 Hz, GNSS 5 Hz (every fifth without a
// fix), odometry 20 Hz, and /tf_static once.
std::string RigBag(const RigOptions& rig, Ros1BagWriter::Compression compression) {
  Ros1BagWriter::Options options;
  options.compression = compression;
  Ros1BagWriter w(options);
  const uint32_t tf = w.AddConnection("/tf_static", "tf2_msgs/TFMessage");
  const uint32_t imu = w.AddConnection("/imu/data", "sensor_msgs/Imu");
  const uint32_t lidar = w.AddConnection("/velodyne_points", "sensor_msgs/PointCloud2");
  const uint32_t wheel = w.AddConnection("/joint_states", "sensor_msgs/JointState");
  const uint32_t gnss = w.AddConnection("/fix", "sensor_msgs/NavSatFix");
  const uint32_t odom = w.AddConnection("/odom", "nav_msgs/Odometry");
  const uint32_t imu2 = rig.second_imu ? w.AddConnection("/imu/raw", "sensor_msgs/Imu") : 0;
  w.Write(
      tf, kStartNs,
      test::SerializeTfMessage(false, kStartNs,
                               {{"base_link", "imu_link", kQBaseImu, kPBaseImu},
                                {"base_link", "velodyne", kQBaseLidar, kPBaseLidar},
                                {"/base_link", "gps", Eigen::Quaterniond::Identity(), kPBaseGps}}));
  for (int i = 0; i < 400; ++i) {
    const int64_t t = kStartNs + i * 5000000LL;
    // A turn on the spot about the gravity axis (+y in the IMU), its rate growing: the
    // accelerometer stays steady while the gyro moves far beyond a still gyro's noise.
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const bool nan_here = rig.non_finite_values && (i == 100 || i == 40 || i == 80);
    std::string bytes = test::SerializeImu(
        false, t - kHeaderLagNs, "imu_link",
        {0, i == 100 && nan_here ? nan : rig.gyro_scale * 0.005 * i, 0}, {0, 9.81, 0});
    if (rig.corrupt_imu && i == 200) bytes.resize(bytes.size() - 1);
    w.Write(imu, t, bytes);
    if (rig.second_imu) w.Write(imu2, t, bytes);
    if (i % 20 == 0 && !(rig.two_fixes_300_s_apart && i > 0)) {
      w.Write(lidar, t + 1000, Cloud(t - kHeaderLagNs, i / 20));
    }
    if (i % 4 == 0) {
      std::vector<double> velocity = rig.joint_velocities
                                         ? std::vector<double>{1, 2, 3.0 + i, 4.0 + i}
                                         : std::vector<double>{};
      if (i == 80 && nan_here) velocity = {1, 2, nan, nan};
      const int64_t stamp = rig.repeated_joint_stamp && i == 40 ? t - 20'000'000 : t;
      w.Write(wheel, t + 2000,
              test::SerializeJointState(false, stamp - kHeaderLagNs, rig.joints,
                                        {0, 0, 0.01 * i, 0.02 * i}, velocity));
    }
    if (i % 40 == 0) {
      int8_t status = (i / 40) % 5 == 4 ? -1 : 0;
      int64_t stamp = t - kHeaderLagNs;
      if (rig.two_fixes_300_s_apart) {
        status = i == 0 || i == 360 ? 0 : -1;
        if (i == 360) stamp = kStartNs - kHeaderLagNs + 300'000'000'000LL;
      }
      w.Write(gnss, t + 3000,
              test::SerializeNavSatFix(
                  false, stamp, status, 48.0 + 1e-6 * i, 11.0,
                  rig.gnss_altitude_nan ? std::numeric_limits<double>::quiet_NaN() : 500.0,
                  {4.0, 9.0, 16.0}, rig.gnss_covariance_type));
    }
    if (i % 10 == 0) {
      w.Write(odom, t + 4000,
              test::SerializeOdometry(false, t - kHeaderLagNs, i == 40 && nan_here ? nan : 0.01 * i,
                                      -0.5));
    }
  }
  return w.Finish();
}

class ImportBagTest : public ::testing::Test {
 protected:
  std::string Bag(const RigOptions& rig,
                  Ros1BagWriter::Compression compression = Ros1BagWriter::Compression::kLz4) {
    const std::string path = (test::OutputDir("in") / "rig.bag").string();
    Ros1BagWriter::WriteFile(path, RigBag(rig, compression));
    return path;
  }
  // Imports the rig's bag with the default options into *options' output.
  ImportSummary ImportRig(const RigOptions& rig, ImportOptions* options) {
    *options = Options(Bag(rig));
    return ImportBag(*options);
  }
  ImportOptions Options(const std::string& bag) {
    ImportOptions options;
    options.input = bag;
    options.output = (test::OutputDir("out") / "dataset").string();
    fs::remove_all(test::OutputDir("out"));  // a previous run's output
    fs::create_directories(test::OutputDir("out"));
    return options;
  }
};

TEST_F(ImportBagTest, EveryStreamLandsInADatasetTheReaderAccepts) {
  const ImportOptions options = Options(Bag(RigOptions()));
  const ImportSummary summary = ImportBag(options);
  EXPECT_EQ(summary.imu.topic, "/imu/data");
  EXPECT_EQ(summary.lidar.written, 20);
  EXPECT_EQ(summary.static_transforms, 1);

  const io::Dataset dataset = io::ReadDataset(options.output);
  ASSERT_EQ(dataset.imu.size(), 400u);
  EXPECT_EQ(dataset.imu.front().t_ns, kStartNs - kHeaderLagNs);  // header stamps
  EXPECT_EQ(dataset.imu[10].gyro_rad_s, Eigen::Vector3d(0, 0.005 * 10, 0));
  EXPECT_EQ(dataset.imu[10].accel_m_s2, Eigen::Vector3d(0, 9.81, 0));
  EXPECT_NEAR(dataset.sensors.imu.noise.update_rate_hz, 200.0, 1e-9);

  // The rear wheels among four joints, by name; velocities as recorded.
  ASSERT_EQ(dataset.wheel.size(), 100u);
  EXPECT_EQ(dataset.wheel[1].left_rad_s, 7.0);
  EXPECT_EQ(dataset.wheel[1].right_rad_s, 8.0);

  // Every fifth fix has no fix; sigma from the covariance diagonal (E, N, U).
  ASSERT_EQ(dataset.gnss.size(), 8u);
  EXPECT_EQ(dataset.gnss[0].std_enu_m, Eigen::Vector3d(2, 3, 4));
  EXPECT_EQ(dataset.gnss[1].lat_deg, 48.0 + 40e-6);

  ASSERT_EQ(dataset.lidar_sweeps.size(), 20u);
  EXPECT_EQ(dataset.lidar_sweeps[1].t_ns, kStartNs + 20 * 5000000LL - kHeaderLagNs);
  const lidar::LidarSweep sweep = dataset.LoadSweep(1);
  ASSERT_EQ(sweep.cloud.size(), 100);
  EXPECT_NEAR(sweep.cloud.time_s[50], 0.05, 1e-7);
  EXPECT_NEAR(sweep.cloud.points(1, 0), 0.1, 1e-6);
  ASSERT_TRUE(dataset.sensors.lidar.has_value());
  EXPECT_NEAR(dataset.sensors.lidar->rate_hz, 10.0, 1e-9);

  // T_I_L = T_base_imu^-1 T_base_lidar, T_I_V = T_base_imu^-1, p_I_A through "/base_link".
  const geometry::Pose3d T_base_imu(kQBaseImu, kPBaseImu);
  const geometry::Pose3d T_base_lidar(kQBaseLidar, kPBaseLidar);
  const geometry::Pose3d T_I_L = T_base_imu.Inverse() * T_base_lidar;
  const sensors::Calibration& nominal = dataset.sensors.nominal_calibration;
  EXPECT_TRUE(nominal.q_I_L.isApprox(T_I_L.q, 1e-12));
  EXPECT_TRUE(nominal.p_I_L.isApprox(T_I_L.p, 1e-12));
  EXPECT_TRUE(nominal.q_I_V.isApprox(T_base_imu.Inverse().q, 1e-12));
  EXPECT_TRUE(nominal.p_I_V.isApprox(T_base_imu.Inverse().p, 1e-12));
  EXPECT_TRUE(nominal.p_I_A.isApprox(T_base_imu.Inverse() * kPBaseGps, 1e-12));

  std::ifstream odometry(options.output + "/odometry.csv");
  std::string header, first, second;
  std::getline(odometry, header);
  std::getline(odometry, first);
  std::getline(odometry, second);
  EXPECT_EQ(header, "t_ns,speed_m_s,yaw_rate_rad_s");
  EXPECT_EQ(second, std::to_string(kStartNs + 10 * 5000000LL - kHeaderLagNs) + ",0.1,-0.5");
  EXPECT_FALSE(fs::exists(options.output + "/groundtruth"));
}

TEST_F(ImportBagTest, ReceiveTimesOnRequest) {
  ImportOptions options = Options(Bag(RigOptions(), Ros1BagWriter::Compression::kBz2));
  options.use_receive_time = true;
  ImportBag(options);
  const io::Dataset dataset = io::ReadDataset(options.output);
  EXPECT_EQ(dataset.imu.front().t_ns, kStartNs);
  EXPECT_EQ(dataset.gnss.front().t_ns, kStartNs + 3000);
}

TEST_F(ImportBagTest, WheelRatesFromPositionsWhenVelocitiesAreMissing) {
  RigOptions rig;
  rig.joint_velocities = false;
  ImportOptions options = Options(Bag(rig));
  options.left_wheel_joint = "rear_left_wheel";
  options.right_wheel_joint = "rear_right_wheel";
  ImportBag(options);
  const io::Dataset dataset = io::ReadDataset(options.output);
  ASSERT_EQ(dataset.wheel.size(), 99u);  // the first message has nothing to differ from
  // Angles 0.01 i and 0.02 i rad, a message every 4 samples of 5 ms: 2 and 4 rad/s.
  EXPECT_NEAR(dataset.wheel[5].left_rad_s, 2.0, 1e-9);
  EXPECT_NEAR(dataset.wheel[5].right_rad_s, 4.0, 1e-9);
  // Each difference is the rate midway between its two messages, and stamped there (at the
  // later message it lagged by half their interval, 10 ms here: a wheel clock offset).
  RigOptions with_velocities;
  ImportOptions stamped = Options(Bag(with_velocities));
  stamped.left_wheel_joint = "rear_left_wheel";
  stamped.right_wheel_joint = "rear_right_wheel";
  ImportBag(stamped);
  const io::Dataset messages = io::ReadDataset(stamped.output);
  ASSERT_EQ(messages.wheel.size(), 100u);
  for (size_t i = 0; i < dataset.wheel.size(); ++i) {
    EXPECT_EQ(dataset.wheel[i].t_ns, (messages.wheel[i].t_ns + messages.wheel[i + 1].t_ns) / 2)
        << i;
  }
}

// A positions-only JointState stamped as the one before it has no interval to differ over: it is
// dropped and counted, and the next message differs from the last one in order (the angle
// difference over the time between them). It used to become the reference for the next rate,
// which came out halved.
TEST_F(ImportBagTest, AJointStampThatDoesNotAdvanceIsDroppedAndCounted) {
  RigOptions rig;
  rig.joint_velocities = false;
  rig.repeated_joint_stamp = true;
  ImportOptions options = Options(Bag(rig));
  options.left_wheel_joint = "rear_left_wheel";
  options.right_wheel_joint = "rear_right_wheel";
  const ImportSummary summary = ImportBag(options);
  const io::Dataset dataset = io::ReadDataset(options.output);
  ASSERT_EQ(dataset.wheel.size(), 98u);
  for (const sensors::WheelSample& w : dataset.wheel) {
    EXPECT_NEAR(w.left_rad_s, 2.0, 1e-9) << w.t_ns;
  }
  EXPECT_THAT(summary.warnings,
              ::testing::Contains(HasSubstr("1 JointState messages (positions only) whose stamp "
                                            "did not follow the previous one's were dropped")));
}

// A NaN in an IMU, odometry or JointState message drops that message, counted; it used to fail
// the whole import when the CSV was written, naming a temporary file that was then deleted.
// Wheel velocities a driver does not know (NaN) are taken from the joints' angles.
TEST_F(ImportBagTest, NonFiniteValuesDropTheirMessageCounted) {
  RigOptions rig;
  rig.non_finite_values = true;
  ImportOptions options;
  const ImportSummary summary = ImportRig(rig, &options);
  EXPECT_EQ(summary.imu.written, 399);
  EXPECT_EQ(summary.odometry.written, 39);
  EXPECT_EQ(summary.wheel.written, 100);
  const std::vector<std::string>& warnings = summary.warnings;
  EXPECT_THAT(warnings, ::testing::Contains(
                            HasSubstr("1 IMU messages with a non-finite angular velocity or linear "
                                      "acceleration were dropped")));
  EXPECT_THAT(warnings, ::testing::Contains(
                            HasSubstr("1 odometry messages with a non-finite speed or yaw rate")));
  const io::Dataset dataset = io::ReadDataset(options.output);
  // Message 20 (i = 80) from its angles 0.8 and 1.6 rad and message 19's 0.76 and 1.52 rad,
  // 20 ms apart, stamped midway.
  const sensors::WheelSample& from_angles = dataset.wheel[20];
  EXPECT_EQ(from_angles.t_ns, (dataset.wheel[19].t_ns + dataset.wheel[21].t_ns) / 2 - 10'000'000);
  EXPECT_NEAR(from_angles.left_rad_s, 2.0, 1e-9);
  EXPECT_NEAR(from_angles.right_rad_s, 4.0, 1e-9);
  EXPECT_EQ(dataset.wheel[21].left_rad_s, 3.0 + 84);
}

// A stream whose rate sensors.yaml cannot state (two fixes 300 s apart, one lone sweep) is left
// out with a warning; it used to fail the whole import, IMU included, naming a temporary file.
TEST_F(ImportBagTest, AStreamWithoutARateIsLeftOutNotTheImport) {
  ImportOptions options;
  RigOptions rig;
  rig.two_fixes_300_s_apart = true;
  const ImportSummary summary = ImportRig(rig, &options);
  EXPECT_EQ(summary.lidar.written, 0);
  EXPECT_EQ(summary.gnss.written, 0);
  EXPECT_THAT(summary.warnings,
              ::testing::Contains(HasSubstr("/fix: left out of the dataset: 2 GNSS fixes over "
                                            "300 s (0.00333333 Hz), not a stream at the 0.01 to "
                                            "1000 Hz sensors.yaml can state")));
  EXPECT_THAT(
      summary.warnings,
      ::testing::Contains(HasSubstr("/velodyne_points: left out of the dataset: 1 sweeps")));
  EXPECT_THAT(summary.FormatText(), ::testing::Not(HasSubstr("importing")));
  const io::Dataset dataset = io::ReadDataset(options.output);
  EXPECT_EQ(dataset.imu.size(), 400u);
  EXPECT_TRUE(dataset.gnss.empty());
  EXPECT_TRUE(dataset.lidar_sweeps.empty());
  EXPECT_FALSE(dataset.sensors.gnss.has_value());
  EXPECT_FALSE(dataset.sensors.lidar.has_value());
  EXPECT_FALSE(fs::exists(options.output + "/lidar"));
}

TEST_F(ImportBagTest, WheelsThatNamesDoNotTellApartNeedAFlag) {
  RigOptions rig;
  rig.joints = {"left_front", "left_middle", "right_front", "right_middle"};
  ImportOptions options = Options(Bag(rig));
  try {
    ImportBag(options);
    FAIL() << "guessed the wheels";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("cannot tell the left and right rear wheels"));
    EXPECT_THAT(e.what(), HasSubstr("--wheel_joints=LEFT,RIGHT"));
  }
  options.left_wheel_joint = "left_middle";
  options.right_wheel_joint = "right_middle";
  ImportBag(options);
  const io::Dataset dataset = io::ReadDataset(options.output);
  ASSERT_EQ(dataset.wheel.size(), 100u);
  EXPECT_EQ(dataset.wheel[1].left_rad_s, 2.0);
  EXPECT_EQ(dataset.wheel[1].right_rad_s, 8.0);
}

// Fixes without an altitude (NaN: every RMC fix of nmea_navsat_driver) are dropped with their
// own count and reason; they were counted as fixes with status < 0. Their position is not
// checked against the covariance first: with no default sigma they failed the import.
TEST_F(ImportBagTest, FixesWithoutAnAltitudeAreDroppedForWhatTheyLack) {
  RigOptions rig;
  rig.gnss_altitude_nan = true;
  rig.gnss_covariance_type = 0;
  ImportOptions options = Options(Bag(rig));
  options.unknown_gnss_sigma_m = 0.0;
  const ImportSummary summary = ImportBag(options);
  EXPECT_TRUE(io::ReadDataset(options.output).gnss.empty());
  EXPECT_THAT(summary.warnings,
              ::testing::Contains(HasSubstr("8 GNSS fixes with a non-finite latitude, longitude "
                                            "or altitude")));
  EXPECT_THAT(summary.warnings, ::testing::Contains(HasSubstr("2 GNSS messages without a fix")));
}

TEST_F(ImportBagTest, UnknownGnssCovarianceTakesTheDefaultOrIsRefused) {
  RigOptions rig;
  rig.gnss_covariance_type = 0;
  ImportOptions options = Options(Bag(rig));
  options.unknown_gnss_sigma_m = 3.0;
  const ImportSummary summary = ImportBag(options);
  EXPECT_EQ(io::ReadDataset(options.output).gnss[0].std_enu_m, Eigen::Vector3d(3, 3, 3));
  EXPECT_THAT(summary.FormatText(), HasSubstr("without a usable covariance got sigma 3 m"));

  options.output += "_refused";
  options.unknown_gnss_sigma_m = 0.0;
  EXPECT_THROW(ImportBag(options), ParseError);
  EXPECT_FALSE(fs::exists(options.output));
}

TEST_F(ImportBagTest, SeveralTopicsOfOneTypeNeedAFlag) {
  RigOptions rig;
  rig.second_imu = true;
  ImportOptions options = Options(Bag(rig));
  try {
    ImportBag(options);
    FAIL() << "imported an ambiguous bag";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("/imu/data, /imu/raw"));
    EXPECT_THAT(e.what(), HasSubstr("--imu_topic=TOPIC"));
  }
  EXPECT_FALSE(fs::exists(options.output));
  options.imu_topic = "/imu/raw";
  options.lidar_topic = "none";
  const ImportSummary summary = ImportBag(options);
  EXPECT_EQ(summary.imu.topic, "/imu/raw");
  EXPECT_TRUE(summary.lidar.topic.empty());
  EXPECT_FALSE(fs::exists(options.output + "/lidar.csv"));
}

TEST_F(ImportBagTest, NonEmptyOutputIsRefusedBeforeTheBagIsRead) {
  ImportOptions options;
  options.input = "/nonexistent/bag.bag";
  options.output = (test::OutputDir("out") / "full").string();
  fs::remove_all(options.output);
  fs::create_directories(options.output);
  std::ofstream(options.output + "/keep.txt") << "mine";
  try {
    ImportBag(options);
    FAIL() << "wrote into a non-empty directory";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("exists and is not empty"));
  }
  EXPECT_TRUE(fs::exists(options.output + "/keep.txt"));
}

TEST_F(ImportBagTest, FailedImportLeavesNoDirectory) {
  RigOptions rig;
  rig.corrupt_imu = true;
  const ImportOptions options = Options(Bag(rig));
  try {
    ImportBag(options);
    FAIL() << "imported a short IMU message";
  } catch (const ParseError& e) {
    EXPECT_THAT(e.what(), HasSubstr("sensor_msgs/Imu message on /imu/data"));
    EXPECT_THAT(e.what(), HasSubstr("message too short for its type"));
  }
  EXPECT_FALSE(fs::exists(options.output));
  // Nor a temporary one beside it.
  for (const auto& entry : fs::directory_iterator(fs::path(options.output).parent_path())) {
    ADD_FAILURE() << "left behind: " << entry.path();
  }
}

TEST_F(ImportBagTest, DataTheDatasetReaderRefusesIsNotWritten) {
  RigOptions rig;
  rig.gyro_scale = kRadToDeg;
  const ImportOptions options = Options(Bag(rig));
  try {
    ImportBag(options);
    FAIL() << "imported a gyroscope in deg/s";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("fails the dataset checks, nothing was written: imu.csv:"));
    EXPECT_THAT(e.what(), HasSubstr("deg/s"));
    EXPECT_THAT(e.what(), ::testing::Not(HasSubstr("importing")));
  }
  EXPECT_FALSE(fs::exists(options.output));
}

TEST_F(ImportBagTest, ListTopicsCountsEveryMessage) {
  const std::vector<TopicListing> topics = ListTopics(Bag(RigOptions()));
  ASSERT_EQ(topics.size(), 6u);
  EXPECT_EQ(topics[1].topic, "/imu/data");
  EXPECT_EQ(topics[1].message_count, 400u);
  EXPECT_NEAR(topics[1].mean_rate_hz(), 200.0, 1e-9);
  EXPECT_NEAR(topics[1].span_s(), 1.995, 1e-12);
  EXPECT_THAT(FormatTopicList(topics), HasSubstr("/velodyne_points"));
}

}  // namespace
}  // namespace import
}  // namespace autocal
