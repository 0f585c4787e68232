// The ground height field is the integral of its grades, and the drive stays on it.

#include <gtest/gtest.h>

#include <cmath>

#include "autocal/common/units.h"
#include "autocal/sim/scenario.h"

namespace autocal {
namespace sim {
namespace {

class GroundTest : public ::testing::TestWithParam<ScenarioType> {};

Scenario MakeScenario(ScenarioType type) {
  ScenarioOptions options;
  options.type = type;
  options.duration_s = 60.0;
  options.seed = 11;
  return BuildScenario(options);
}

TEST_P(GroundTest, HeightIsTheIntegralOfTheGrade) {
  const Scenario scenario = MakeScenario(GetParam());
  for (const GradeProfile* profile : {&scenario.ground->along_x(), &scenario.ground->along_y()}) {
    ASSERT_GT(profile->transitions().size(), 2u);
    EXPECT_NEAR(profile->Height(0.0), 0.0, 1e-12);
    const double h = 1e-3;
    // Across every transition (where the grade changes) and between them.
    for (const GradeProfile::Transition& tr : profile->transitions()) {
      for (double f = -0.2; f <= 1.2; f += 0.05) {
        const double u = tr.u_begin + f * (tr.u_end - tr.u_begin);
        const double slope = (profile->Height(u + h) - profile->Height(u - h)) / (2.0 * h);
        EXPECT_NEAR(slope, profile->Grade(u), 1e-8) << "at u = " << u;
      }
      // No step in height at the ends of a transition.
      for (double end : {tr.u_begin, tr.u_end}) {
        EXPECT_NEAR(profile->Height(end + 1e-9), profile->Height(end - 1e-9), 1e-9)
            << "at u = " << end;
      }
    }
  }
}

TEST_P(GroundTest, TheDriveStaysOnTheGround) {
  // The rear-axle centre rides rear_axle_height_m above the road along the normal, and the
  // body's z axis stays within a few degrees (suspension roll and pitch) of that normal.
  const Scenario scenario = MakeScenario(GetParam());
  const VehicleTrajectory& trajectory = *scenario.trajectory;
  const GroundSurface& ground = *scenario.ground;
  const double axle = trajectory.dynamics().rear_axle_height_m;
  for (double t = 0.0; t <= 60.0; t += 0.25) {
    const geometry::Pose3d T_W_V = trajectory.PoseAt(t);
    const Eigen::Vector2d g = ground.Gradient(T_W_V.p.x(), T_W_V.p.y());
    const Eigen::Vector3d normal = Eigen::Vector3d(-g.x(), -g.y(), 1.0).normalized();
    const Eigen::Vector3d road = T_W_V.p - axle * normal;
    EXPECT_NEAR(road.z(), ground.Height(road.x(), road.y()), 1e-4) << "at t = " << t;
    const double tilt_deg = std::acos(std::min(1.0, normal.dot(T_W_V.R().col(2)))) * kRadToDeg;
    EXPECT_LT(tilt_deg, 3.0) << "at t = " << t;
  }
}

INSTANTIATE_TEST_SUITE_P(Scenarios, GroundTest,
                         ::testing::Values(ScenarioType::kUrban, ScenarioType::kHighway),
                         [](const auto& info) { return ScenarioName(info.param); });

}  // namespace
}  // namespace sim
}  // namespace autocal
