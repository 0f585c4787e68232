#pragma once

// What the offline and the online tests of GNSS noise from the residuals (Eq. N2) share: a
// log whose receiver states every fix's std four times too small, and what its result must
// show against the same log's with the std as simulated.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <map>
#include <string>

#include "autocal/io/calibration_yaml.h"
#include "autocal/io/dataset.h"

namespace autocal {
namespace test {

// `dataset` with every fix's std divided by four.
inline io::Dataset WithOptimisticGnssStd(io::Dataset dataset) {
  for (sensors::GnssFix& fix : dataset.gnss) fix.std_enu_m /= 4.0;
  return dataset;
}

// Both axis groups scaled by about the four the std was divided by (the fitted residuals read
// a little low).
inline void ExpectGnssScaledByAboutFour(const io::CalibrationFile& result) {
  const std::map<std::string, double>& gnss = result.residuals.at("gnss");
  for (const char* key : {"noise_scale_horizontal", "noise_scale_vertical"}) {
    EXPECT_GT(gnss.at(key), 3.0) << key;
    EXPECT_LT(gnss.at(key), 4.4) << key;
  }
}

// ExpectGnssScaledByAboutFour, and the lever arm as from the fixes as stated: the same
// observability, its sigma within 10 % and its value within 0.2 sigma of `stated`'s.
inline void ExpectScaledGnssAndTheLeverArmAsStated(const io::CalibrationFile& result,
                                                   const io::CalibrationFile& stated) {
  ExpectGnssScaledByAboutFour(result);
  const io::VectorBlockInfo& expected = stated.uncertainty.p_I_A_m;
  const io::VectorBlockInfo& got = result.uncertainty.p_I_A_m;
  ASSERT_TRUE(expected.sigma.has_value());
  ASSERT_TRUE(got.sigma.has_value());
  EXPECT_EQ(got.observable, expected.observable);
  const Eigen::Vector3d moved_m = result.value.p_I_A - stated.value.p_I_A;
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR((*got.sigma)(a), (*expected.sigma)(a), 0.1 * (*expected.sigma)(a)) << a;
    EXPECT_LT(std::abs(moved_m(a)), 0.2 * (*expected.sigma)(a)) << a;
  }
}

}  // namespace test
}  // namespace autocal
