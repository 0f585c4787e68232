// The coverage analysis (docs/coverage.md) against the course's numbers (§1.3 and the
// exercises of §2) and against rigs built to pass and to fail.
#include "autocal/coverage/coverage.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/io/coverage_yaml.h"

namespace autocal {
namespace coverage {
namespace {

using ::testing::HasSubstr;

std::string Shipped(const std::string& file) {
  return (std::filesystem::path(AUTOCAL_SOURCE_DIR) / "coverage" / file).string();
}

// Eq. (1) and the course's figures: 120 km/h at 5 m/s^2 stops in about 110 m; following at
// 120 km/h needs about 165 m; the exercises at 150 km/h: a 2 s gap of 83.33 m and a braking
// distance of 173.61 m.
TEST(CoverageDistances, ReproduceTheCoursesNumbers) {
  EXPECT_NEAR(BrakingDistanceM(120.0 / 3.6, 5.0), 111.11, 0.005);
  EXPECT_NEAR(BrakingDistanceM(150.0 / 3.6, 5.0), 173.61, 0.005);
  Scenario highway = io::ScenarioPreset("highway");
  EXPECT_NEAR(EmergencyStopRangeM(highway), 111.11, 0.005);
  EXPECT_NEAR(FollowingRangeM(highway), 166.67, 0.005);  // v^2/4 - v^2/10
  highway.speed_m_s = 150.0 / 3.6;
  EXPECT_NEAR(highway.speed_m_s * highway.time_gap_s, 83.33, 0.005);
  // A reaction time adds v t_r to both; a slow speed leaves the time gap the longer.
  highway.speed_m_s = 120.0 / 3.6;
  highway.reaction_time_s = 0.5;
  EXPECT_NEAR(EmergencyStopRangeM(highway), 111.11 + 16.67, 0.01);
  const Scenario urban = io::ScenarioPreset("urban");
  EXPECT_NEAR(FollowingRangeM(urban), std::max(27.78, 48.23 - 19.29), 0.01);
  EXPECT_NEAR(OncomingRangeM(urban), 2.0 * 50.0 / 3.6 * 5.0, 1e-9);
  EXPECT_THROW(BrakingDistanceM(10.0, 0.0), Error);
}

TEST(CoverageRequirements, PlaceEachManeuversRegions) {
  const Body body;
  const std::vector<Maneuver> highway = Requirements(io::ScenarioPreset("highway"), body);
  ASSERT_EQ(highway.size(), 3u);
  EXPECT_EQ(highway[0].name, "emergency_stop");
  const std::vector<Eigen::Vector2d>& lane = highway[0].regions.at(0).polygon;
  EXPECT_NEAR(lane[1].x() - lane[0].x(), 111.11, 0.005);  // from the front bumper
  EXPECT_NEAR(lane[0].x(), body.front_m, 1e-12);
  EXPECT_NEAR(lane[2].y() - lane[1].y(), 3.7, 1e-12);
  EXPECT_EQ(Requirements(io::ScenarioPreset("urban"), body).size(), 6u);
  Scenario odd = io::ScenarioPreset("urban");
  odd.maneuvers = {"parking"};
  EXPECT_THROW(Requirements(odd, body), Error);
}

// What one sensor sees: range, the horizontal and vertical fields of view, the body.
TEST(CoverageSees, RangeFieldsOfViewAndTheBody) {
  const Body body;  // x -1 ... 3.8, |y| <= 0.95, z <= 1.5
  Sensor lidar{"roof lidar", SensorType::kLidar, {1.3, 0.0, 1.95}, 0.0,   0.0,
               2.0 * M_PI,   -25.0 * kDegToRad,  15.0 * kDegToRad, 120.0, 0.0};
  EXPECT_TRUE(Sees(lidar, body, {20.0, 0.0, 0.5}));
  EXPECT_FALSE(Sees(lidar, body, {130.0, 0.0, 0.5}));  // out of range
  // A point 0.5 m in front of the bumper: the hood and the roof edge hide it.
  EXPECT_FALSE(Sees(lidar, body, {4.3, 0.0, 0.5}));
  // A forward camera sees 30 deg to each side, not 40.
  Sensor camera{"camera",         SensorType::kCamera, {1.9, 0.0, 1.4},  0.0,   0.0,
                60.0 * kDegToRad, -20.0 * kDegToRad,   20.0 * kDegToRad, 100.0, 0.0};
  EXPECT_TRUE(Sees(camera, body, {50.0, 50.0 * std::tan(25.0 * kDegToRad), 0.5}));
  EXPECT_FALSE(Sees(camera, body, {50.0, 50.0 * std::tan(35.0 * kDegToRad), 0.5}));
  // Behind the windscreen (inside the body) it looks out; it sees nothing behind anyway.
  EXPECT_FALSE(Sees(camera, body, {-20.0, 0.0, 0.5}));
  // Pitched down by 30 deg it sees the near ground and loses the horizon.
  camera.pitch_rad = 30.0 * kDegToRad;
  EXPECT_TRUE(Sees(camera, body, {5.0, 0.0, 0.0}));
  EXPECT_FALSE(Sees(camera, body, {50.0, 0.0, 1.4}));
  // A rear-facing sensor just outside the front bumper: the body hides everything behind.
  Sensor backwards{"rear view",      SensorType::kRadar, {3.9, 0.0, 0.5},  M_PI, 0.0,
                   60.0 * kDegToRad, -10.0 * kDegToRad,  10.0 * kDegToRad, 80.0, 0.0};
  EXPECT_FALSE(Sees(backwards, body, {-20.0, 0.0, 0.5}));
}

// The shipped rigs: the one after the course's Fig. 5 covers both scenarios, a lone forward
// camera neither, and the table names what is short.
TEST(CoverageAnalysis, ShippedRigsPassAndFailAsBuilt) {
  const Rig full = io::ReadRigYaml(Shipped("rigs/full_rig.yaml"));
  const Rig camera = io::ReadRigYaml(Shipped("rigs/front_camera_only.yaml"));
  for (const char* name : {"highway", "urban"}) {
    for (const ManeuverCoverage& m : AnalyzeCoverage(full, io::ScenarioPreset(name))) {
      EXPECT_TRUE(m.covered) << name << " " << m.name;
    }
  }
  // The margin past the emergency stop's lane: the front radar's 250 m beyond the 115 m lane
  // end, capped at 100 m, is not the weakest corner; the corners beside the hood are.
  const ManeuverCoverage stop_full = AnalyzeCoverage(full, io::ScenarioPreset("highway"))[0];
  EXPECT_GT(stop_full.regions[0].margin_m, 0.0);
  EXPECT_LE(stop_full.regions[0].margin_m, 100.0);
  const std::vector<ManeuverCoverage> lone = AnalyzeCoverage(camera, io::ScenarioPreset("highway"));
  ASSERT_EQ(lone.size(), 3u);
  for (const ManeuverCoverage& m : lone) EXPECT_FALSE(m.covered) << m.name;
  // Emergency stop: the camera's 100 m fall short of the 111 m (plus the 3.8 m hood).
  const RegionCoverage& stop = lone[0].regions[0];
  EXPECT_GT(stop.worst_range_m, 100.0);
  EXPECT_LT(stop.covered_fraction, 0.95);
  const RegionCoverage& behind = lone[2].regions.back();
  EXPECT_EQ(behind.region.name, "own lane behind");
  EXPECT_EQ(behind.covered_fraction, 0.0);
  const std::string table = CoverageTable(camera, lone);
  EXPECT_THAT(table, HasSubstr("| lane_change | own lane behind | 60 m behind | 0.0 % | short"));
  EXPECT_THAT(table, HasSubstr("| none |"));
  const std::string svg = CoverageSvg(camera, lone);
  EXPECT_THAT(svg, HasSubstr("<svg xmlns='http://www.w3.org/2000/svg'"));
  EXPECT_THAT(svg, HasSubstr("stroke='#d22'"));  // short regions in red
  EXPECT_THAT(svg, HasSubstr("</svg>"));
  Rig odd = camera;
  odd.name = "<rig & co>";
  EXPECT_THAT(CoverageSvg(odd, lone), HasSubstr("&lt;rig &amp; co&gt;"));
}

}  // namespace
}  // namespace coverage
}  // namespace autocal
