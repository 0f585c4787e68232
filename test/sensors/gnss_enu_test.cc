#include "autocal/sensors/gnss_enu.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <GeographicLib/Geocentric.hpp>
#include <GeographicLib/LocalCartesian.hpp>
#include <cmath>
#include <random>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/units.h"

namespace autocal {
namespace sensors {
namespace {

// Origins across the globe; points up to ~5 km away in every direction and height.
TEST(EnuConverter, MatchesGeographicLibLocalCartesian) {
  const double origins[][3] = {{49.011, 8.4164, 115.0},
                               {-33.86, 151.21, 40.0},
                               {64.14, -21.94, 20.0},
                               {0.5, -78.5, 2850.0},
                               {37.77, -122.42, -30.0}};
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const auto& o : origins) {
    const EnuConverter converter(o[0], o[1], o[2]);
    const GeographicLib::LocalCartesian reference(o[0], o[1], o[2]);
    for (int k = 0; k < 50; ++k) {
      const double lat = o[0] + 0.05 * u(rng), lon = o[1] + 0.05 * u(rng),
                   alt = o[2] + 100 * u(rng);
      Eigen::Vector3d expected;
      reference.Forward(lat, lon, alt, expected.x(), expected.y(), expected.z());
      const Eigen::Vector3d enu = converter.ToEnu(lat, lon, alt);
      EXPECT_LT((enu - expected).norm(), 1e-9) << enu.transpose() << " vs " << expected.transpose();
      const Eigen::Vector3d lla = converter.ToGeodetic(enu);
      EXPECT_NEAR(lla.x(), lat, 1e-11);
      EXPECT_NEAR(lla.y(), lon, 1e-11);
      EXPECT_NEAR(lla.z(), alt, 1e-6);
    }
  }
}

// The axes are east, north, up: an independent check through ECEF (WGS84 Geocentric) and
// the ENU rotation at the origin.
TEST(EnuConverter, AxesAreEastNorthUp) {
  const double lat0 = 48.137, lon0 = 11.575, alt0 = 519.0;
  const EnuConverter converter(lat0, lon0, alt0);
  const GeographicLib::Geocentric& earth = GeographicLib::Geocentric::WGS84();
  Eigen::Vector3d origin_ecef;
  earth.Forward(lat0, lon0, alt0, origin_ecef.x(), origin_ecef.y(), origin_ecef.z());
  const double phi = lat0 * kDegToRad, lambda = lon0 * kDegToRad;
  const Eigen::Vector3d east(-std::sin(lambda), std::cos(lambda), 0.0);
  const Eigen::Vector3d north(-std::sin(phi) * std::cos(lambda), -std::sin(phi) * std::sin(lambda),
                              std::cos(phi));
  const Eigen::Vector3d up = east.cross(north);
  const double points[][3] = {{lat0 + 0.001, lon0, alt0},
                              {lat0, lon0 + 0.001, alt0},
                              {lat0, lon0, alt0 + 10.0},
                              {lat0 - 0.002, lon0 + 0.003, alt0 - 5.0}};
  for (const auto& pt : points) {
    Eigen::Vector3d ecef;
    earth.Forward(pt[0], pt[1], pt[2], ecef.x(), ecef.y(), ecef.z());
    const Eigen::Vector3d d = ecef - origin_ecef;
    const Eigen::Vector3d expected(east.dot(d), north.dot(d), up.dot(d));
    const Eigen::Vector3d enu = converter.ToEnu(pt[0], pt[1], pt[2]);
    EXPECT_LT((enu - expected).norm(), 1e-6) << enu.transpose() << " vs " << expected.transpose();
  }
  EXPECT_GT(converter.ToEnu(lat0 + 0.001, lon0, alt0).y(), 100.0);  // north is +y
  EXPECT_GT(converter.ToEnu(lat0, lon0 + 0.001, alt0).x(), 70.0);   // east is +x
}

TEST(EnuConverter, OriginAtFirstFixAndCopies) {
  GnssFixes fixes(2);
  fixes[0].lat_deg = 52.52;
  fixes[0].lon_deg = 13.405;
  fixes[0].alt_m = 34.0;
  fixes[1] = fixes[0];
  fixes[1].lat_deg += 0.01;
  const EnuConverter converter = EnuConverter::AtFirstFix(fixes);
  EXPECT_LT(converter.ToEnu(fixes[0]).norm(), 1e-9);
  EnuConverter copy = converter;
  EXPECT_LT((copy.ToEnu(fixes[1]) - converter.ToEnu(fixes[1])).norm(), 1e-12);
  copy = EnuConverter(0.0, 0.0, 0.0);
  EXPECT_GT((copy.ToEnu(fixes[1]) - converter.ToEnu(fixes[1])).norm(), 1e5);
}

TEST(EnuConverter, RejectsInvalidPositions) {
  EXPECT_THROW(EnuConverter(91.0, 0.0, 0.0), Error);
  EXPECT_THROW(EnuConverter(0.0, std::nan(""), 0.0), Error);
  EXPECT_THROW(EnuConverter::AtFirstFix(GnssFixes{}), Error);
  const EnuConverter converter(10.0, 10.0, 0.0);
  try {
    converter.ToEnu(10.0, 190.0, 0.0);
    ADD_FAILURE() << "no error for longitude 190";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("lon 190"), std::string::npos) << e.what();
  }
  EXPECT_THROW(converter.ToGeodetic(Eigen::Vector3d(0.0, std::nan(""), 0.0)), Error);
}

}  // namespace
}  // namespace sensors
}  // namespace autocal
