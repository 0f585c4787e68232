#include "autocal/io/calibration_block_fields.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

namespace autocal {
namespace io {
namespace {

// A value per block and direction that no other block shares.
Eigen::VectorXd Distinct(const sensors::CalibrationBlockInfo& block) {
  Eigen::VectorXd v(block.tangent_size);
  for (int k = 0; k < block.tangent_size; ++k) {
    v(k) = 1.0 + static_cast<int>(block.id) + 0.1 * (k + 1);
  }
  return v;
}

// Every block has a field of its own in a problem: setting all of them with distinct values
// reads each one back unchanged.
TEST(CalibrationBlockFields, EveryBlockHasItsOwnProblemSetting) {
  ProblemCalibration problem;
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    SetBlockSetting(block.id, {BlockMode::kPrior, Distinct(block)}, &problem);
  }
  std::set<std::string> keys;
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    const BlockModeAndSigma read = BlockSettingIn(problem, block.id);
    EXPECT_EQ(read.mode, BlockMode::kPrior) << block.key;
    EXPECT_EQ(read.prior_sigma, Distinct(block)) << block.key;
    keys.insert(ProblemKey(block.id));
  }
  EXPECT_EQ(keys.size(), sensors::CalibrationBlocks().size());
  EXPECT_EQ(problem.T_I_V.rotation.prior_sigma(2),
            Distinct(sensors::CalibrationBlock(sensors::CalibrationBlockId::kVehicleRotation))(2));
  EXPECT_STREQ(ProblemKey(sensors::CalibrationBlockId::kGnssLeverArm), "p_I_A_m");
}

// The same for an uncertainty; a pose's two halves share six flags, rotation first.
TEST(CalibrationBlockFields, EveryBlockHasItsOwnUncertainty) {
  CalibrationUncertainty u;
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    EXPECT_FALSE(UncertaintyIn(u, block.id).sigma) << block.key;
    std::vector<bool> flags(static_cast<size_t>(block.tangent_size), true);
    flags.back() = false;
    SetBlockUncertainty(block.id, Distinct(block), &flags, &u);
  }
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    const BlockUncertainty read = UncertaintyIn(u, block.id);
    ASSERT_TRUE(read.sigma) << block.key;
    EXPECT_EQ(*read.sigma, Distinct(block)) << block.key;
    ASSERT_EQ(read.observable.size(), static_cast<size_t>(block.tangent_size)) << block.key;
    EXPECT_FALSE(read.observable.back()) << block.key;
    EXPECT_TRUE(read.observable.front() || block.tangent_size == 1) << block.key;
  }
  EXPECT_EQ(u.T_I_L.observable, std::vector<bool>({true, true, false, true, true, false}));
}

}  // namespace
}  // namespace io
}  // namespace autocal
