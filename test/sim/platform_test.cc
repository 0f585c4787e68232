// The slow skid-steer platform (pivots on the spot, closed laps, an effective track), the
// straight drive, and the presets after real logs written as datasets with their clock truth.

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/io/dataset.h"
#include "autocal/sim/simulator.h"
#include "sim/sim_test_util.h"
#include "support/test_paths.h"

namespace autocal {
namespace sim {
namespace {

double Yaw(const geometry::Pose3d& T_W_V) {
  const Eigen::Matrix3d R = T_W_V.R();
  return std::atan2(R(1, 0), R(0, 0));
}

// The three beam layouts the simulator knows (autocal_simulate --lidar_beams); the default
// configuration is the 32-beam one.
TEST(PlatformTest, SpinningLidarBeamLayouts) {
  sensors::LidarConfig config;
  const sensors::LidarConfig default_config;
  SetSpinningLidarBeams(32, &config);
  EXPECT_EQ(config.num_beams, default_config.num_beams);
  EXPECT_EQ(config.min_elevation_deg, default_config.min_elevation_deg);
  EXPECT_EQ(config.max_elevation_deg, default_config.max_elevation_deg);
  SetSpinningLidarBeams(16, &config);
  EXPECT_EQ(config.num_beams, 16);
  EXPECT_EQ(config.min_elevation_deg, -15.0);
  EXPECT_EQ(config.max_elevation_deg, 15.0);
  SetSpinningLidarBeams(64, &config);
  EXPECT_EQ(config.num_beams, 64);
  EXPECT_EQ(config.min_elevation_deg, -24.8);
  EXPECT_EQ(config.max_elevation_deg, 2.0);
  try {
    SetSpinningLidarBeams(17, &config);
    FAIL() << "17 beams were accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("16, 32 or 64"), std::string::npos) << e.what();
  }
  EXPECT_EQ(config.num_beams, 64);  // unchanged by the refusal
}

TEST(PlatformTest, SkidSteerDriveIsSlowPivotsOnTheSpotAndClosesItsLaps) {
  SimulationOptions options = SkidSteerRobotOptions();
  options.duration_s = 600.0;
  const Simulator simulator(options);
  const VehicleTrajectory& trajectory = *simulator.scenario().trajectory;
  const Eigen::Vector3d start = trajectory.PoseAt(0.0).p;
  double max_speed = 0.0, max_range = 0.0, pivot_left_s = 0.0, pivot_right_s = 0.0;
  double last_return_s = 0.0;
  const double h = 0.05;
  for (double t = 0.0; t <= options.duration_s; t += h) {
    const BodyState state = trajectory.StateAt(t);
    const double speed = state.v_W.norm();
    max_speed = std::max(max_speed, speed);
    const double range = (state.T_W_B.p - start).head<2>().norm();
    max_range = std::max(max_range, range);
    if (t > 60.0 && range < 1e-3) last_return_s = t;
    const double yaw_rate = state.omega_B.z();
    // On the spot: turning fast while V's origin (the pivot centre) does not move.
    if (std::abs(yaw_rate) > 0.3 && speed < 1e-9) {
      (yaw_rate > 0.0 ? pivot_left_s : pivot_right_s) += h;
    }
  }
  EXPECT_LE(max_speed, simulator.scenario().limits.max_speed_m_s);
  EXPECT_GT(max_speed, 0.75);
  EXPECT_GT(pivot_left_s, 10.0) << "turns on the spot to the left, s";
  EXPECT_GT(pivot_right_s, 3.0) << "and to the right, s";
  EXPECT_LT(max_range, 60.0) << "the drive stays on its loop";
  // A lap ends where it started (to 1 mm): the robot returns to its start after a minute.
  EXPECT_GT(last_return_s, 100.0);
}

TEST(PlatformTest, SkidSteerWheelsSeeTheEffectiveTrackNotThePhysicalOne) {
  SimulationOptions options = SkidSteerRobotOptions().WithoutNoise();
  options.duration_s = 60.0;
  options.wheel.drop_probability = 0.0;
  const Simulator simulator(options);
  const WheelLog log = simulator.GenerateWheelLog();
  const sensors::Calibration& c = simulator.true_calibration();
  const double physical_track_m = 0.555;
  double pivot_samples = 0, worst = 0.0, ratio_sum = 0.0;
  for (size_t i = 0; i < log.samples.size(); ++i) {
    const double t_imu =
        simulator.TimeOf(log.samples[i].t_ns) + options.wheel.time_offset_wheel_imu_s;
    EXPECT_NEAR(NsToSeconds(log.true_t_ns[i] - options.start_time_ns), t_imu, 1e-9);
    const BodyState state = simulator.scenario().trajectory->StateAt(t_imu);
    const double v_l = log.samples[i].left_rad_s * c.wheel_radius_left_m;
    const double v_r = log.samples[i].right_rad_s * c.wheel_radius_right_m;
    // The true yaw rate is the wheel speed difference over the effective track.
    worst = std::max(worst, std::abs((v_r - v_l) / c.track_width_m - state.omega_B.z()));
    if (std::abs(state.omega_B.z()) > 0.3 && std::abs(0.5 * (v_l + v_r)) < 1e-9) {
      ratio_sum += (v_r - v_l) / physical_track_m / state.omega_B.z();
      ++pivot_samples;
    }
  }
  EXPECT_LT(worst, 1e-9);
  ASSERT_GT(pivot_samples, 20);
  // Read with the physical track, the encoders overstate the yaw rate by the slip factor.
  EXPECT_NEAR(ratio_sum / pivot_samples, 1.875, 1e-9);
}

TEST(PlatformTest, StraightDriveKeepsItsHeadingAndChangesSpeed) {
  const Simulator simulator(test::SmallLog(ScenarioType::kStraight, 60.0));
  const VehicleTrajectory& trajectory = *simulator.scenario().trajectory;
  const double yaw0 = Yaw(trajectory.PoseAt(0.0));
  double worst_yaw = 0.0, max_speed = 0.0, min_moving_speed = 1e9, stop_s = 0.0;
  bool moving = false;
  for (double t = 0.0; t <= 60.0; t += 0.05) {
    const BodyState state = trajectory.StateAt(t);
    worst_yaw = std::max(worst_yaw, std::abs(std::remainder(Yaw(state.T_W_B) - yaw0, 2 * M_PI)));
    const double speed = state.v_W.norm();
    max_speed = std::max(max_speed, speed);
    if (speed > 5.0) moving = true;
    if (moving && speed > 5.0) min_moving_speed = std::min(min_moving_speed, speed);
    if (moving && speed < 1e-6) stop_s += 0.05;
  }
  // The path keeps one heading; the body's yaw moves only as the banked road tilts it.
  for (double s = 0.0; s < trajectory.path().length_m(); s += 1.0) {
    ASSERT_EQ(trajectory.path().Heading(s), trajectory.path().Heading(0.0)) << "at s = " << s;
  }
  EXPECT_LT(worst_yaw, 2e-3) << "rad";
  EXPECT_LT(max_speed, simulator.scenario().limits.max_speed_m_s);
  EXPECT_GT((max_speed - min_moving_speed) * 3.6, 20.0) << "speed changes, km/h";
  EXPECT_GT(stop_s, 1.5) << "a stop after the start, s";
}

TEST(PlatformTest, LidarPointsLieOnSurfacesWhileTheRobotPivots) {
  // The skid-steer preset with a LiDAR: the IMU is mounted y-up and the robot turns on the
  // spot, so the sweep checks the mount chain T_W_I T_I_L and the pivot kinematics together.
  SimulationOptions options = SkidSteerRobotOptions().WithoutNoise();
  options.duration_s = 12.0;
  options.lidar.enabled = true;
  options.lidar.config.num_beams = 16;
  options.lidar.config.azimuth_resolution_deg = 1.0;
  const Simulator simulator(options);
  const sensors::Calibration& truth = simulator.true_calibration();
  const geometry::Pose3d T_I_L(truth.q_I_L, truth.p_I_L);
  int pivot_sweeps = 0;
  for (int k = 0; k < simulator.num_sweeps(); k += 5) {
    const lidar::LidarSweep sweep = simulator.GenerateSweep(k);
    const double t0 = simulator.TimeOf(sweep.t_ns) + truth.time_offset_lidar_imu_s;
    const BodyState state = simulator.scenario().trajectory->StateAt(t0);
    if (std::abs(state.omega_B.z()) < 0.3 || state.v_W.norm() > 1e-9) continue;
    ++pivot_sweeps;
    ASSERT_GT(sweep.cloud.size(), 1000);
    double worst = 0.0;
    for (int64_t i = 0; i < sweep.cloud.size(); ++i) {
      const double t = t0 + sweep.cloud.time_s(i);
      const Eigen::Vector3d p_W =
          simulator.ImuPoseAt(t) * (T_I_L * Eigen::Vector3d(sweep.cloud.points.col(i)));
      worst = std::max(worst, simulator.scenario().world->DistanceToSurface(p_W, t));
    }
    EXPECT_LT(worst, 1e-6) << "sweep " << k;
  }
  EXPECT_GE(pivot_sweeps, 3);
}

// A preset written as a dataset reads back, and groundtruth/timing.yaml holds its offsets.
void CheckPresetDataset(SimulationOptions options, const std::string& name) {
  const Simulator simulator(options);
  const std::string directory = (autocal::test::OutputDir("sim_platform") / name).string();
  WriteDataset(simulator, directory);
  const io::Dataset dataset = io::ReadDataset(directory);
  const WheelLog wheel = simulator.GenerateWheelLog();
  ASSERT_EQ(dataset.wheel.size(), wheel.samples.size());
  for (size_t i = 0; i < wheel.samples.size(); i += 7) {
    ASSERT_EQ(dataset.wheel[i].t_ns, wheel.samples[i].t_ns);
  }
  ASSERT_EQ(dataset.imu.size(), simulator.GenerateImu().samples.size());
  const YAML::Node timing = YAML::LoadFile(directory + "/groundtruth/timing.yaml");
  EXPECT_EQ(timing["time_offset_wheel_imu_s"].as<double>(), options.wheel.time_offset_wheel_imu_s);
  EXPECT_EQ(timing["time_offset_gnss_imu_s"].as<double>(), options.gnss.time_offset_gnss_imu_s);
  EXPECT_EQ(timing["wheel"]["burst_size"].as<int>(), options.wheel.burst_size);
  EXPECT_EQ(timing["imu"]["rate_hz"].as<double>(), options.imu.noise.update_rate_hz);
  // The nominal mount in sensors.yaml is the round one the preset states.
  EXPECT_LT(geometry::AngularDistance(dataset.sensors.nominal_calibration.q_I_V,
                                      *options.nominal_perturbation.q_I_V),
            1e-9);
  // So is the rear axle's slip (Eq. K6c).
  ASSERT_TRUE(dataset.sensors.wheel.has_value());
  EXPECT_EQ(dataset.sensors.wheel->lateral_slip_sigma_m_s,
            options.wheel.config.lateral_slip_sigma_m_s);
  EXPECT_EQ(dataset.sensors.wheel->cornering_compliance_rad_per_m_s2,
            options.wheel.config.cornering_compliance_rad_per_m_s2);
}

TEST(PlatformTest, SkidSteerPresetWritesItsClockTruth) {
  SimulationOptions options = SkidSteerRobotOptions();
  options.duration_s = 20.0;
  CheckPresetDataset(options, "skid_steer");
  // A skid steer slides sideways in every turn: it states the platform defaults, not a road
  // car's slip.
  EXPECT_EQ(options.wheel.config.lateral_slip_sigma_m_s,
            sensors::WheelConfig().lateral_slip_sigma_m_s);
  EXPECT_EQ(options.wheel.config.cornering_compliance_rad_per_m_s2, 0.0);
  // Standing at the start, the y-up IMU feels gravity on its y axis.
  const ImuLog imu = Simulator(options).GenerateImu();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int k = 0; k < 30; ++k) mean += imu.samples[k].accel_m_s2 / 30.0;
  EXPECT_GT(mean.y(), 9.5) << mean.transpose();
}

TEST(PlatformTest, CanBusCarPresetWritesItsClockTruth) {
  SimulationOptions options = CanBusCarOptions();
  options.duration_s = 10.0;
  CheckPresetDataset(options, "can_bus_car");
  EXPECT_EQ(options.wheel.config.lateral_slip_sigma_m_s,
            RoadCarWheelConfig().lateral_slip_sigma_m_s);
  EXPECT_GT(options.wheel.config.cornering_compliance_rad_per_m_s2, 0.0);
  const ImuLog imu = Simulator(options).GenerateImu();
  EXPECT_LT(imu.samples.front().accel_m_s2.z(), -9.5) << "z down";
}

}  // namespace
}  // namespace sim
}  // namespace autocal
