// Any IMU mounting: the simulator assumes nothing about R_V_I. Turning the IMU in place
// (WithImuMount) rotates its measurements and nothing else: wheel rates, GNSS fixes and
// LiDAR sweeps stay the same. The nominal mount can be set far from the truth.

#include <gtest/gtest.h>

#include <cmath>

#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"
#include "autocal/sim/simulator.h"
#include "sim/sim_test_util.h"

namespace autocal {
namespace sim {
namespace {

// The mounts of the real platforms: y up (R_V_I = Rz(-90) Rx(+90)) and z down (Rx(180)).
Eigen::Quaterniond YUp() { return RotationFromRollPitchYawDeg(90.0, 0.0, -90.0); }
Eigen::Quaterniond ZDown() { return RotationFromRollPitchYawDeg(180.0, 0.0, 0.0); }

geometry::Pose3d T_V_I(const sensors::Calibration& c) {
  return geometry::Pose3d(c.q_I_V, c.p_I_V).Inverse();
}

TEST(MountTest, RollPitchYawFollowTheConvention) {
  // Rz(-90) Rx(+90): the IMU's y axis points up, its x axis to the right (-y_V).
  const Eigen::Matrix3d R = YUp().toRotationMatrix();
  EXPECT_TRUE((R * Eigen::Vector3d::UnitY()).isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
  EXPECT_TRUE((R * Eigen::Vector3d::UnitX()).isApprox(-Eigen::Vector3d::UnitY(), 1e-12));
  const Eigen::Matrix3d D = ZDown().toRotationMatrix();
  EXPECT_TRUE((D * Eigen::Vector3d::UnitZ()).isApprox(-Eigen::Vector3d::UnitZ(), 1e-12));
  EXPECT_TRUE((D * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitX(), 1e-12));
}

TEST(MountTest, WithImuMountKeepsTheImuOriginTheLidarAndTheAntennaInTheVehicle) {
  const sensors::Calibration before = DefaultTrueCalibration();
  const sensors::Calibration after = WithImuMount(before, YUp());
  const geometry::Pose3d T_V_I_before = T_V_I(before), T_V_I_after = T_V_I(after);
  EXPECT_LT(geometry::AngularDistance(T_V_I_after.q, YUp()), 1e-12);
  EXPECT_LT((T_V_I_after.p - T_V_I_before.p).norm(), 1e-12);
  const geometry::Pose3d T_V_L_before = T_V_I_before * geometry::Pose3d(before.q_I_L, before.p_I_L);
  const geometry::Pose3d T_V_L_after = T_V_I_after * geometry::Pose3d(after.q_I_L, after.p_I_L);
  EXPECT_LT(geometry::AngularDistance(T_V_L_before.q, T_V_L_after.q), 1e-12);
  EXPECT_LT((T_V_L_before.p - T_V_L_after.p).norm(), 1e-12);
  EXPECT_LT((T_V_I_before * before.p_I_A - T_V_I_after * after.p_I_A).norm(), 1e-12);
  EXPECT_EQ(after.track_width_m, before.track_width_m);
}

TEST(MountTest, TurningTheImuRotatesItsSignalsAndChangesNoOtherSensor) {
  SimulationOptions options = test::SmallLog(ScenarioType::kUrban, 8.0).WithoutNoise();
  options.lidar.config.azimuth_resolution_deg = 2.0;
  const Simulator reference(options);
  for (const Eigen::Quaterniond& mount : {YUp(), ZDown()}) {
    SimulationOptions turned_options = options;
    turned_options.true_calibration = WithImuMount(options.true_calibration, mount);
    const Simulator turned(turned_options);
    const ImuLog a = reference.GenerateImu();
    const ImuLog b = turned.GenerateImu();
    ASSERT_EQ(a.samples.size(), b.samples.size());
    // Same point of the body, other axes: f_b = R_b_a f_a, omega_b = R_b_a omega_a.
    const Eigen::Matrix3d R_b_a =
        (turned_options.true_calibration.q_I_V * options.true_calibration.q_I_V.conjugate())
            .toRotationMatrix();
    double worst_f = 0.0, worst_w = 0.0;
    for (size_t k = 0; k < a.samples.size(); ++k) {
      worst_f =
          std::max(worst_f, (b.samples[k].accel_m_s2 - R_b_a * a.samples[k].accel_m_s2).norm());
      worst_w =
          std::max(worst_w, (b.samples[k].gyro_rad_s - R_b_a * a.samples[k].gyro_rad_s).norm());
    }
    EXPECT_LT(worst_f, 1e-9);
    EXPECT_LT(worst_w, 1e-12);
    // Standing at the start: the specific force is gravity reversed, in the IMU's axes, and
    // mostly along the IMU axis that points up in V (the road is graded by a few percent).
    const Eigen::Vector3d f0 = b.samples.front().accel_m_s2;
    const Eigen::Vector3d up_W_in_I =
        b.truth.front().T_W_I.q.conjugate() * Eigen::Vector3d::UnitZ();
    EXPECT_LT((f0 - 9.80665 * up_W_in_I).norm(), 1e-9);
    const Eigen::Vector3d up_V_in_I =
        turned_options.true_calibration.q_I_V * Eigen::Vector3d::UnitZ();
    EXPECT_GT(f0.dot(up_V_in_I), 9.7) << f0.transpose();

    const sensors::WheelSamples wa = reference.GenerateWheel(), wb = turned.GenerateWheel();
    ASSERT_EQ(wa.size(), wb.size());
    for (size_t i = 0; i < wa.size(); ++i) {
      ASSERT_EQ(wa[i].left_rad_s, wb[i].left_rad_s);
      ASSERT_EQ(wa[i].right_rad_s, wb[i].right_rad_s);
    }
    const GnssLog ga = reference.GenerateGnss(), gb = turned.GenerateGnss();
    ASSERT_EQ(ga.fixes.size(), gb.fixes.size());
    for (size_t i = 0; i < ga.fixes.size(); ++i) {
      ASSERT_LT((ga.true_p_W_A[i] - gb.true_p_W_A[i]).norm(), 1e-9);
    }
    ASSERT_EQ(reference.num_sweeps(), turned.num_sweeps());
    const int k = reference.num_sweeps() / 2;
    const lidar::LidarSweep sa = reference.GenerateSweep(k), sb = turned.GenerateSweep(k);
    ASSERT_EQ(sa.cloud.size(), sb.cloud.size());
    ASSERT_GT(sa.cloud.size(), 1000);
    EXPECT_LT((sa.cloud.points - sb.cloud.points).cwiseAbs().maxCoeff(), 1e-6);
  }
}

TEST(MountTest, NominalMountCanBeSetFarFromTheTruth) {
  SimulationOptions options = test::SmallLog(ScenarioType::kUrban, 2.0);
  options.true_calibration = WithImuMount(options.true_calibration, YUp());
  const Simulator drawn(options);
  // A guess 30 degrees off the true mount.
  const Eigen::Quaterniond guess = (options.true_calibration.q_I_V *
                                    Eigen::Quaterniond(Eigen::AngleAxisd(
                                        30.0 * kDegToRad, Eigen::Vector3d(1, 1, 0).normalized())))
                                       .normalized();
  options.nominal_perturbation.q_I_V = guess;
  options.nominal_perturbation.q_I_V_sigma_deg = 40.0;
  const Simulator set(options);
  EXPECT_LT(geometry::AngularDistance(set.nominal_calibration().q_I_V, guess), 1e-12);
  EXPECT_NEAR(
      geometry::AngularDistance(set.nominal_calibration().q_I_V, set.true_calibration().q_I_V) /
          kDegToRad,
      30.0, 1e-9);
  // A drawn nominal mount stays near the truth; every other nominal value is unchanged.
  EXPECT_LT(
      geometry::AngularDistance(drawn.nominal_calibration().q_I_V, drawn.true_calibration().q_I_V),
      10.0 * kDegToRad);
  EXPECT_EQ(set.nominal_calibration().p_I_V, drawn.nominal_calibration().p_I_V);
  EXPECT_EQ(set.nominal_calibration().p_I_A, drawn.nominal_calibration().p_I_A);
  EXPECT_EQ(set.nominal_calibration().q_I_L.coeffs(), drawn.nominal_calibration().q_I_L.coeffs());
  const io::SensorsConfig config = set.sensors_config();
  EXPECT_EQ(config.nominal_uncertainty.T_I_V.sigma_rot_deg, Eigen::Vector3d::Constant(40.0));
  EXPECT_EQ(config.nominal_uncertainty.T_I_L.sigma_rot_deg,
            Eigen::Vector3d::Constant(options.nominal_perturbation.rotation_deg));
}

}  // namespace
}  // namespace sim
}  // namespace autocal
