// Which calibration blocks the sliding window has settings for, and the error for the others.

#include "autocal/estimation/sliding_window_blocks.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace {

using Id = sensors::CalibrationBlockId;

// Every block of angular-rate wheels has a setting; the blocks of the other wheel forms and
// the wheel and GNSS clocks are refused by name, and never count as estimated.
// The window takes every wheel form; the clock offsets (held by the pipeline) are not its
// blocks.
TEST(SlidingWindowBlocks, TheClockOffsetsAreNotSupported) {
  SlidingWindowEstimatedBlocks estimate;
  SlidingWindowCalibrationPrior prior;
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    const bool other_form = info.id == Id::kWheelTimeOffset || info.id == Id::kGnssTimeOffset;
    EXPECT_EQ(WindowSupports(info.id), !other_form) << info.key;
    if (!other_form) {
      const SlidingWindowBlockSetting setting = BlockSettingOf(info.id, &estimate, &prior);
      EXPECT_NE(setting.estimate, nullptr) << info.key;
      EXPECT_NE(setting.prior_sigma, nullptr) << info.key;
      continue;
    }
    EXPECT_FALSE(Estimated(info.id, estimate)) << info.key;
    try {
      BlockSettingOf(info.id, &estimate, &prior);
      ADD_FAILURE() << info.key << ": no error";
    } catch (const Error& e) {
      EXPECT_THAT(e.what(), ::testing::HasSubstr(std::string("calibration block ") + info.key +
                                                 " is not supported by the sliding window"));
    }
  }
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
