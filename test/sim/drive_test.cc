// The simulated drives respect their scenario's limits, are smooth (continuous acceleration)
// and carry the excitation a calibration needs.

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include "autocal/common/units.h"
#include "autocal/sim/scenario.h"
#include "autocal/sim/simulator.h"
#include "sim/scenario_parts.h"
#include "sim/sim_test_util.h"

namespace autocal {
namespace sim {
namespace {

class DriveTest : public ::testing::TestWithParam<ScenarioType> {};

// The scenario's speed, horizontal acceleration and jerk over [0, duration_s] against its limits.
void ExpectWithinLimits(const Scenario& scenario, double duration_s) {
  const DriveLimits& limits = scenario.limits;
  const VehicleTrajectory& trajectory = *scenario.trajectory;
  const double h = 0.01;
  BodyState previous = trajectory.StateAt(0.0);
  double max_speed = 0.0, min_speed = 1e9, max_accel = 0.0, max_jerk = 0.0, jerk_t = 0.0;
  for (double t = h; t <= duration_s; t += h) {
    const BodyState state = trajectory.StateAt(t);
    const double speed = state.v_W.norm();
    max_speed = std::max(max_speed, speed);
    min_speed = std::min(min_speed, speed);
    max_accel = std::max(max_accel, state.a_W.head<2>().norm());
    const double jerk = (state.a_W - previous.a_W).norm() / h;
    if (jerk > max_jerk) max_jerk = jerk, jerk_t = t;
    previous = state;
  }
  EXPECT_LE(max_speed, limits.max_speed_m_s) << "km/h: " << max_speed * 3.6;
  EXPECT_GE(min_speed, limits.min_cruise_speed_m_s) << "km/h: " << min_speed * 3.6;
  EXPECT_LE(max_accel, limits.max_horizontal_accel_m_s2);
  EXPECT_LE(max_jerk, limits.max_jerk_m_s3) << "at t = " << jerk_t << " s";
  if (scenario.type == ScenarioType::kHighway) {
    EXPECT_GT(max_speed * 3.6, 110.0) << "a highway drive runs at about 120 km/h";
  }
}

TEST_P(DriveTest, SpeedAccelerationAndJerkStayWithinTheScenarioLimits) {
  // 90 s cover every urban maneuver (turns, stops, roundabout, overtaking) and every
  // highway one (lane changes, curves, speed changes).
  const Simulator simulator(test::SmallLog(GetParam(), 90.0));
  ExpectWithinLimits(simulator.scenario(), simulator.options().duration_s);
}

// Every seed gives a drive: the random maneuvers are drawn within what the path can build.
// Highway seeds 7 and 25 drew curves whose entry and exit ramps alone turned more than the
// curve's angle, and the simulator refused them.
TEST_P(DriveTest, EverySeedPlansADrive) {
  for (uint64_t seed = 1; seed <= 60; ++seed) {
    ScenarioOptions options;
    options.type = GetParam();
    options.duration_s = 10.0;
    options.seed = seed;
    EXPECT_NO_THROW(BuildScenario(options)) << "seed " << seed;
  }
}

// A curve too gentle for its ramps is ramped in and out at once: it turns by the requested
// angle, reaches the circle's curvature and stays within the highway's limits.
TEST(DriveTest, ACurveTooGentleForItsRampsTurnsByItsAngle) {
  const double turn_rad = 7.0 * kDegToRad, radius_m = 900.0, ramp_m = 120.0;
  ASSERT_LT(turn_rad * radius_m, ramp_m) << "the ramps alone would turn more";
  internal::DriveBuilder drive(0.3, 33.0);
  drive.Cruise(50.0);
  drive.Arc(turn_rad, radius_m, ramp_m);
  const PathProfile& path = drive.path();
  EXPECT_NEAR(path.final_heading_rad() - 0.3, turn_rad, 1e-12);
  EXPECT_NEAR(path.length_m(), 50.0 + 2.0 * turn_rad * radius_m, 1e-9);
  EXPECT_NEAR(path.Curvature(50.0 + turn_rad * radius_m), 1.0 / radius_m, 1e-12);

  ScenarioOptions options;
  options.type = ScenarioType::kHighway;
  options.duration_s = 60.0;
  options.seed = 7;  // draws a curve of 7.2 deg at 944 m
  ExpectWithinLimits(BuildScenario(options), options.duration_s);
}

TEST_P(DriveTest, AccelerationOfTheImuIsContinuous) {
  // C^2: over 1 ms the IMU's acceleration changes by at most jerk * 1 ms. A jump (a kink in
  // velocity) anywhere in the drive would show up as a change orders of magnitude larger.
  const Simulator simulator(test::SmallLog(GetParam(), 30.0));
  const VehicleTrajectory& trajectory = *simulator.scenario().trajectory;
  const geometry::Pose3d T_V_I =
      geometry::Pose3d(simulator.true_calibration().q_I_V, simulator.true_calibration().p_I_V)
          .Inverse();
  const double h = 1e-3;
  BodyState previous = trajectory.StateAt(0.0, T_V_I);
  double worst = 0.0, worst_t = 0.0;
  double worst_omega = 0.0;
  for (double t = h; t <= simulator.options().duration_s; t += h) {
    const BodyState state = trajectory.StateAt(t, T_V_I);
    const double change = (state.a_W - previous.a_W).norm();
    if (change > worst) worst = change, worst_t = t;
    worst_omega = std::max(worst_omega, (state.omega_B - previous.omega_B).norm());
    previous = state;
  }
  EXPECT_LT(worst, 10.0 * h) << "acceleration jumps by " << worst << " m/s^2 at t = " << worst_t;
  EXPECT_LT(worst_omega, 2.0 * h) << "body rate jumps by " << worst_omega << " rad/s";
}

TEST(DriveTest, UrbanDriveHasStandstillTurnsStopsAndGrades) {
  const Simulator simulator(test::SmallLog(ScenarioType::kUrban, 120.0));
  const VehicleTrajectory& trajectory = *simulator.scenario().trajectory;
  double standstill_at_start = 0.0, total_turn = 0.0, stops = 0.0;
  double min_pitch = 1e9, max_pitch = -1e9;
  bool moving = false;
  const double h = 0.02;
  for (double t = 0.0; t <= 120.0; t += h) {
    const BodyState state = trajectory.StateAt(t);
    const double speed = state.v_W.norm();
    if (speed < 1e-3 && t < 5.0 && !moving) standstill_at_start += h;
    if (speed > 1.0) moving = true;
    if (moving && speed < 1e-3) {
      stops += h;
    }
    total_turn += std::abs(state.omega_B.z()) * h;
    const double pitch = std::asin(state.T_W_B.R()(2, 0)) * -kRadToDeg;
    min_pitch = std::min(min_pitch, pitch);
    max_pitch = std::max(max_pitch, pitch);
  }
  EXPECT_GE(standstill_at_start, 1.0) << "the drive starts standing";
  EXPECT_GE(stops, 2.0) << "seconds standing after the start";
  // Several 90-degree turns and a roundabout in two minutes.
  EXPECT_GE(total_turn * kRadToDeg, 360.0);
  EXPECT_GE(max_pitch - min_pitch, 2.0) << "road grades give pitch excitation, deg";
}

// With a rear-axle cornering compliance c the body yaws into each turn by c v^2 kappa from the
// direction the axle travels, so V's origin moves sideways in V at -v sin(c v^2 kappa); without
// it the axle does not slip. Measured against the same drive without slip (the suspension's
// roll and pitch give the rest of the lateral speed, identical in both).
TEST(DriveTest, TheRearAxleSlipsOutOfTheTurnByItsCorneringCompliance) {
  SimulationOptions options = test::SmallLog(ScenarioType::kUrban, 60.0);
  const Simulator ideal(options);
  const double compliance = 0.3 * kDegToRad;  // rad per m/s^2
  options.dynamics.rear_slip_per_lateral_accel = compliance;
  const Simulator slipping(options);
  const VehicleTrajectory& a = *ideal.scenario().trajectory;
  const VehicleTrajectory& b = *slipping.scenario().trajectory;
  const auto lateral_m_s = [](const BodyState& state) {
    return (state.T_W_B.q.conjugate() * state.v_W).y();
  };
  double largest_slip_m_s = 0.0, largest_ideal_m_s = 0.0, worst_error_m_s = 0.0;
  for (double t = 0.0; t <= 60.0; t += 0.05) {
    const BodyState without = a.StateAt(t), with = b.StateAt(t);
    const double s = a.ArcLengthAt(t);
    const double v = without.v_W.head<2>().norm();
    const double slip_rad = compliance * v * v * a.path().Curvature(s);
    const double expected_m_s = -v * std::sin(slip_rad);
    const double slip_m_s = lateral_m_s(with) - lateral_m_s(without);
    worst_error_m_s = std::max(worst_error_m_s, std::abs(slip_m_s - expected_m_s));
    largest_slip_m_s = std::max(largest_slip_m_s, std::abs(slip_m_s));
    largest_ideal_m_s = std::max(largest_ideal_m_s, std::abs(lateral_m_s(without)));
  }
  std::cout << "largest slip " << largest_slip_m_s << " m/s, off -v sin(c v^2 kappa) by at most "
            << worst_error_m_s << " m/s; ideal axle's lateral speed up to " << largest_ideal_m_s
            << " m/s\n";
  EXPECT_GT(largest_slip_m_s, 0.02) << "the roundabout's and the turn's slip, m/s";
  EXPECT_LT(worst_error_m_s, 1e-3);
  // Without slip only the body's roll tilting V's y axis into the grade's vertical speed.
  EXPECT_LT(largest_ideal_m_s, 0.01) << "the ideal axle's lateral speed, m/s";
  // sensors.yaml states at least the simulated slip (Eq. K6c).
  options.dynamics.rear_slip_per_lateral_accel = 2.0 * compliance;
  EXPECT_EQ(Simulator(options).sensors_config().wheel->cornering_compliance_rad_per_m_s2,
            2.0 * compliance);
  EXPECT_EQ(slipping.sensors_config().wheel->cornering_compliance_rad_per_m_s2,
            RoadCarWheelConfig().cornering_compliance_rad_per_m_s2);
}

INSTANTIATE_TEST_SUITE_P(Scenarios, DriveTest,
                         ::testing::Values(ScenarioType::kUrban, ScenarioType::kHighway,
                                           ScenarioType::kSkidSteer, ScenarioType::kStraight),
                         [](const auto& info) { return test::Name(info.param); });

}  // namespace
}  // namespace sim
}  // namespace autocal
