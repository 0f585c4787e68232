#include "autocal/evaluation/information_bound.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"

namespace autocal {
namespace evaluation {
namespace {

// A circle of radius 20 m at 5 m/s, sampled at 100 Hz for 10 s, in the truth's frame.
io::Dataset CircleWithTruth() {
  io::Dataset dataset;
  for (int i = 0; i <= 1000; ++i) {
    const double t = 0.01 * i;
    const double a = 0.25 * t;  // rad
    io::TrajectorySample s;
    s.t_ns = 1'000'000'000 + int64_t{10'000'000} * i;
    s.T_W_I.p = Eigen::Vector3d(20.0 * std::sin(a), 20.0 * (1.0 - std::cos(a)), 0.1 * t);
    s.T_W_I.q = Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()));
    s.v_W_I = Eigen::Vector3d(5.0 * std::cos(a), 5.0 * std::sin(a), 0.1);
    dataset.groundtruth_trajectory.push_back(s);
  }
  sensors::Calibration truth;
  truth.time_offset_lidar_imu_s = 0.0123;
  truth.p_I_A = Eigen::Vector3d(0.1, -0.2, 1.5);
  dataset.groundtruth_calibration = truth;
  return dataset;
}

// The estimate's frame: the truth turned by 30 deg about z and shifted.
const Eigen::Quaterniond kTurn(Eigen::AngleAxisd(30.0 * kDegToRad, Eigen::Vector3d::UnitZ()));
const Eigen::Vector3d kShift(4.0, -7.0, 2.0);

// Keyframes every 0.37 s (between truth samples), the truth in the estimate's frame with the
// positions and velocities off by centimetres, the biases set apart.
std::vector<estimation::Keyframe> KeyframesOff(std::vector<estimation::Keyframe>* exact) {
  std::vector<estimation::Keyframe> keyframes;
  for (int k = 0; k < 25; ++k) {
    const int64_t t_ns = 1'000'000'000 + int64_t{370'000'000} * k + 3'000'000;
    const double t = static_cast<double>(t_ns - 1'000'000'000) * 1e-9;
    const double a = 0.25 * t;
    estimation::Keyframe kf;
    kf.t_ns = t_ns;
    kf.q_W_I = kTurn * Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()));
    kf.p_W_I =
        kTurn * Eigen::Vector3d(20.0 * std::sin(a), 20.0 * (1.0 - std::cos(a)), 0.1 * t) + kShift;
    kf.v_W_I = kTurn * Eigen::Vector3d(5.0 * std::cos(a), 5.0 * std::sin(a), 0.1);
    kf.b_g = Eigen::Vector3d(0.001, 0.002, 0.003) * k;
    exact->push_back(kf);
    kf.p_W_I += Eigen::Vector3d(0.02, -0.01, 0.03) * std::sin(k);
    kf.v_W_I += Eigen::Vector3d(0.01, 0.02, 0.0) * std::cos(k);
    keyframes.push_back(kf);
  }
  return keyframes;
}

TEST(TruthSetter, PutsTheTruthIntoTheEstimatesFrame) {
  const io::Dataset dataset = CircleWithTruth();
  const estimation::StateSetter set_to_truth = TruthSetter(dataset);
  ASSERT_TRUE(set_to_truth);
  std::vector<estimation::Keyframe> exact;
  std::vector<estimation::Keyframe> keyframes = KeyframesOff(&exact);
  sensors::Calibration calibration;
  set_to_truth(&keyframes, &calibration);
  for (size_t k = 0; k < keyframes.size(); ++k) {
    // Interpolated between samples 10 ms apart: the chord of the circle is off by millimetres
    // at most; the alignment's residual from the centimetre offsets is of the same order.
    EXPECT_LT((keyframes[k].p_W_I - exact[k].p_W_I).norm(), 0.01) << k;
    EXPECT_LT(keyframes[k].q_W_I.angularDistance(exact[k].q_W_I), 1e-3) << k;
    EXPECT_LT((keyframes[k].v_W_I - exact[k].v_W_I).norm(), 0.01) << k;
    EXPECT_EQ(keyframes[k].b_g, exact[k].b_g) << k;  // no bias truth: the biases stay
  }
  EXPECT_EQ(calibration.time_offset_lidar_imu_s, 0.0123);
  EXPECT_EQ(calibration.p_I_A, Eigen::Vector3d(0.1, -0.2, 1.5));
}

// With groundtruth/imu_bias.csv the keyframes' biases are the truth's, linear between its
// samples (bias walks are not rotated by the world's yaw: they live in the IMU frame).
TEST(TruthSetter, SetsTheBiasesWhereTheLogHasTheirTruth) {
  io::Dataset dataset = CircleWithTruth();
  const auto bias_at = [](double t) {
    return io::ImuBiasSample{0, Eigen::Vector3d(1e-3, -2e-3, 5e-4) * (1.0 + t),
                             Eigen::Vector3d(0.02, 0.03, -0.01) * (1.0 - 0.05 * t)};
  };
  for (int i = 0; i <= 2000; ++i) {  // 200 Hz, as the simulator's IMU
    io::ImuBiasSample sample = bias_at(0.005 * i);
    sample.t_ns = 1'000'000'000 + int64_t{5'000'000} * i;
    dataset.groundtruth_imu_bias.push_back(sample);
  }
  std::vector<estimation::Keyframe> exact;
  std::vector<estimation::Keyframe> keyframes = KeyframesOff(&exact);
  sensors::Calibration calibration;
  TruthSetter(dataset)(&keyframes, &calibration);
  for (const estimation::Keyframe& kf : keyframes) {
    const io::ImuBiasSample truth = bias_at(static_cast<double>(kf.t_ns - 1'000'000'000) * 1e-9);
    EXPECT_TRUE(kf.b_g.isApprox(truth.b_g, 1e-12)) << kf.b_g.transpose();
    EXPECT_TRUE(kf.b_a.isApprox(truth.b_a, 1e-12)) << kf.b_a.transpose();
  }
}

TEST(TruthSetter, IsEmptyWithoutAGroundTruth) {
  io::Dataset dataset = CircleWithTruth();
  dataset.groundtruth_calibration.reset();
  EXPECT_FALSE(TruthSetter(dataset));
  EXPECT_FALSE(TruthSetter(io::Dataset()));
}

TEST(TruthSetter, RefusesKeyframesOutsideTheTruth) {
  const estimation::StateSetter set_to_truth = TruthSetter(CircleWithTruth());
  std::vector<estimation::Keyframe> keyframes(3);
  keyframes[0].t_ns = 1'000'000'000 + 500'000'000;  // one inside
  keyframes[1].t_ns = 50'000'000'000;
  keyframes[2].t_ns = 60'000'000'000;
  sensors::Calibration calibration;
  EXPECT_THROW(set_to_truth(&keyframes, &calibration), Error);
}

}  // namespace
}  // namespace evaluation
}  // namespace autocal
