// pipeline::SensorFactors::PairingChanges: whether a wheel or GNSS clock the problem estimates
// moved the keyframes onto other samples (docs/keyframe_factors.md, Eq. K17), which decides
// whether the offline calibration without the LiDAR pairs its factors again and solves again.

#include <gtest/gtest.h>

#include <vector>

#include "autocal/common/time.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "pipeline/calibration_steps.h"

namespace autocal {
namespace pipeline {
namespace {

constexpr int64_t kStartNs = 1'700'000'000'000'000'000;

// Wheels at 100 Hz and fixes at 10 Hz over 2 s, keyframes every 0.1 s 37 ms after the fixes.
struct ClockPairing {
  io::Dataset dataset;
  io::Problem problem;
  TimingLimits timing;
  std::vector<estimation::Keyframe> keyframes;
  SensorFactors factors;

  ClockPairing() {
    for (int i = 0; i < 200; ++i) {
      sensors::WheelSample w;
      w.t_ns = kStartNs + SecondsToNs(0.01 * i);
      dataset.wheel.push_back(w);
    }
    for (int i = 0; i < 20; ++i) {
      sensors::GnssFix fix;
      fix.t_ns = kStartNs + SecondsToNs(0.1 * i);
      dataset.gnss.push_back(fix);
    }
    for (int k = 1; k < 18; ++k) {
      estimation::Keyframe kf;
      kf.t_ns = kStartNs + SecondsToNs(0.1 * k + 0.037);
      keyframes.push_back(kf);
    }
    problem.calibration.time_offset_wheel_imu_s.mode = io::BlockMode::kEstimate;
    problem.calibration.time_offset_gnss_imu_s.mode = io::BlockMode::kEstimate;
    timing.max_wheel_gap_s = 0.025;
    timing.max_fix_gap_s = 0.25;
    factors.dataset = &dataset;
    factors.problem = &problem;
    factors.use_wheel = factors.use_gnss = true;
    factors.timing = &timing;
  }

  bool Changes(double wheel_from_s, double wheel_to_s, double gnss_from_s, double gnss_to_s) const {
    sensors::Calibration from, to;
    from.time_offset_wheel_imu_s = wheel_from_s;
    to.time_offset_wheel_imu_s = wheel_to_s;
    from.time_offset_gnss_imu_s = gnss_from_s;
    to.time_offset_gnss_imu_s = gnss_to_s;
    return factors.PairingChanges(keyframes, from, to);
  }
};

// The wheel rows take the rear axle's slip that sensors.yaml states (Eq. K6c), and the defaults
// without a wheel section.
TEST(WheelNoise, TakesTheStatedSlip) {
  io::Dataset dataset;
  estimation::KeyframeWheelOptions rows;
  SetWheelNoise(dataset, dataset.sensors.nominal_calibration, &rows);
  EXPECT_EQ(rows.factor.lateral_sigma_m_s, sensors::WheelConfig().lateral_slip_sigma_m_s);
  EXPECT_EQ(rows.cornering_compliance_rad_per_m_s2, 0.0);
  dataset.sensors.wheel = sensors::WheelConfig();
  dataset.sensors.wheel->lateral_slip_sigma_m_s = 0.012;
  dataset.sensors.wheel->cornering_compliance_rad_per_m_s2 = 0.004;
  SetWheelNoise(dataset, dataset.sensors.nominal_calibration, &rows);
  EXPECT_EQ(rows.factor.lateral_sigma_m_s, 0.012);
  EXPECT_EQ(rows.cornering_compliance_rad_per_m_s2, 0.004);
}

TEST(ClockPairing, ChangesWhenAClockCrossesToOtherSamples) {
  ClockPairing c;
  // Keyframes 37 ms after a fix and 3 ms before a wheel sample (on a 10 ms grid).
  EXPECT_FALSE(c.Changes(0.0, 0.0, 0.0, 0.0));
  EXPECT_FALSE(c.Changes(0.0, 0.0015, 0.0, -0.012));  // the nearest samples stay
  EXPECT_TRUE(c.Changes(0.0, 0.003, 0.0, 0.0));       // wheel: the sample 7 ms early is nearer
  EXPECT_TRUE(c.Changes(0.0, 0.0, 0.0, -0.02));       // GNSS: the fix 63 ms later is nearer
  EXPECT_TRUE(c.Changes(0.003, 0.0, -0.02, 0.0));     // and back

  // A clock the problem holds pairs once, wherever its value.
  c.problem.calibration.time_offset_gnss_imu_s.mode = io::BlockMode::kFixed;
  EXPECT_FALSE(c.Changes(0.0, 0.0, 0.0, -0.02));
  c.problem.calibration.time_offset_wheel_imu_s.mode = io::BlockMode::kPrior;
  EXPECT_TRUE(c.Changes(0.0, 0.003, 0.0, 0.0));
  // And a sensor the problem leaves out, whatever its clock.
  c.factors.use_wheel = false;
  EXPECT_FALSE(c.Changes(0.0, 0.003, 0.0, 0.0));
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
