#include "autocal/estimation/calibration_fusion.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "autocal/common/error.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace estimation {
namespace {

using sensors::CalibrationBlockId;

// A linear Gaussian model of logs: the blocks' tangent x (left radius, lever arm, IMU mount
// rotation: 7 rows) about a truth, a prior N(p, P^-1) and per log z_i = H_i x + noise_i. Log
// i's noise is scatter[i] times the sigma its solve weighs with (1 when `scatter` is empty);
// its widened covariance is then the estimate's, S_i + (scatter_i^2 - 1) S_i D_i S_i (Eq. C8),
// and the joint solution weighs each log by its noise as it is.
struct LinearLogs {
  sensors::Calibration truth;
  std::vector<CalibrationPosterior> posteriors;
  Eigen::VectorXd joint_step;  // the joint least-squares solution, tangent at the truth
  Eigen::MatrixXd joint_covariance;
};

std::vector<EstimatedBlock> Blocks(sensors::Calibration* c,
                                   const std::vector<CalibrationBlockId>& ids,
                                   const sensors::Calibration& prior) {
  std::vector<EstimatedBlock> blocks;
  for (CalibrationBlockId id : ids) {
    EstimatedBlock block = BlockOf(id, c);
    const double* p = sensors::CalibrationBlock(id).const_values(prior);
    block.prior = Eigen::Map<const Eigen::VectorXd>(p, sensors::CalibrationBlock(id).ambient_size);
    block.prior_sigma = Eigen::VectorXd::Constant(
        block.size, id == CalibrationBlockId::kVehicleRotation ? 0.02 : 0.05);
    blocks.push_back(block);
  }
  return blocks;
}

// Sets the blocks of *c to `base` + step (tangent).
void Apply(const std::vector<EstimatedBlock>& blocks, const sensors::Calibration& base,
           const Eigen::VectorXd& step, sensors::Calibration* c) {
  *c = base;
  int row = 0;
  for (const EstimatedBlock& block : blocks) {
    BlockPlus(block, step.segment(row, block.size), sensors::CalibrationBlock(block.id).values(c));
    row += block.size;
  }
}

LinearLogs MakeLogs(int num_logs, double rotation_scale, uint32_t seed,
                    const std::vector<double>& scatter = {}) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal;
  LinearLogs out;
  out.truth.q_I_V = geometry::Exp(Eigen::Vector3d(0.1, -0.2, 0.3));
  const std::vector<CalibrationBlockId> ids = {CalibrationBlockId::kWheelRadiusLeft,
                                               CalibrationBlockId::kVehicleRotation,
                                               CalibrationBlockId::kGnssLeverArm};
  sensors::Calibration scratch = out.truth;
  std::vector<EstimatedBlock> blocks = Blocks(&scratch, ids, out.truth);
  const int n = 7;
  Eigen::VectorXd prior_sigma(n);
  prior_sigma << 0.05, 0.02, 0.02, 0.02, 0.05, 0.05, 0.05;
  prior_sigma.segment(1, 3) *= rotation_scale;
  Eigen::VectorXd p(n);  // prior centre, tangent at the truth
  for (int i = 0; i < n; ++i) p(i) = prior_sigma(i) * normal(rng);
  sensors::Calibration prior_centre;
  Apply(blocks, out.truth, p, &prior_centre);
  const Eigen::MatrixXd P = prior_sigma.array().square().inverse().matrix().asDiagonal();
  Eigen::MatrixXd joint_information = P;
  Eigen::VectorXd joint_vector = P * p;
  for (int i = 0; i < num_logs; ++i) {
    // A log sees some directions well and others hardly (a straight drive, a turning one).
    std::uniform_real_distribution<double> uniform(-1.0, 1.0);
    Eigen::MatrixXd H(5, n);
    for (double& h : H.reshaped()) h = uniform(rng) * (1.0 + i) * 10.0;
    const double k = scatter.empty() ? 1.0 : scatter[static_cast<size_t>(i)];
    Eigen::VectorXd z(5);
    for (int r = 0; r < 5; ++r) z(r) = k * 0.01 * normal(rng);
    const Eigen::MatrixXd R_inv = Eigen::MatrixXd::Identity(5, 5) / 1e-4;
    const Eigen::MatrixXd D = H.transpose() * R_inv * H;
    const Eigen::MatrixXd information = P + D;
    const Eigen::VectorXd vector = P * p + H.transpose() * R_inv * z;
    joint_information += D / (k * k);
    joint_vector += H.transpose() * R_inv * z / (k * k);
    CalibrationPosterior log;
    Apply(blocks, out.truth, information.ldlt().solve(vector), &log.solved);
    log.blocks = Blocks(&log.solved, ids, prior_centre);
    for (size_t b = 0; b < log.blocks.size(); ++b) {
      log.blocks[b].prior_sigma = prior_sigma.segment(b == 0   ? 0
                                                      : b == 1 ? 1
                                                               : 4,
                                                      log.blocks[b].size);
    }
    log.covariance.ok = true;
    log.covariance.offsets = {0, 1, 4};
    log.covariance.matrix = information.inverse();
    log.widened = log.covariance;
    log.widened.matrix += (k * k - 1.0) * log.covariance.matrix * D * log.covariance.matrix;
    out.posteriors.push_back(log);
  }
  out.joint_covariance = joint_information.inverse();
  out.joint_step = joint_information.ldlt().solve(joint_vector);
  return out;
}

Eigen::VectorXd TangentAtTruth(const FusedCalibration& fused, const sensors::Calibration& truth) {
  Eigen::VectorXd x(7);
  for (size_t b = 0; b < fused.blocks.size(); ++b) {
    const EstimatedBlock& block = fused.blocks[b];
    x.segment(fused.covariance.offsets[b], block.size) =
        BlockMinus(block, sensors::CalibrationBlock(block.id).const_values(fused.value),
                   sensors::CalibrationBlock(block.id).const_values(truth));
  }
  return x;
}

// Euclidean directions combine exactly; the rotation to first order in its spread (here
// 1e-5 rad, so to about 1e-10).
TEST(CalibrationFusion, EqualsTheJointLeastSquaresSolution) {
  for (int num_logs : {1, 2, 4}) {
    const LinearLogs logs = MakeLogs(num_logs, 1e-3, 7 + num_logs);
    const FusedCalibration fused = FuseCalibrationPosteriors(logs.posteriors);
    ASSERT_TRUE(fused.covariance.ok);
    ASSERT_EQ(fused.blocks.size(), 3u);
    EXPECT_LT((TangentAtTruth(fused, logs.truth) - logs.joint_step).cwiseAbs().maxCoeff(), 1e-9)
        << num_logs;
    EXPECT_LT((fused.covariance.matrix - logs.joint_covariance).cwiseAbs().maxCoeff(),
              1e-9 * logs.joint_covariance.cwiseAbs().maxCoeff());
  }
}

// Logs whose rows scatter 1-4 times as widely as their noise model says combine, through
// their widened covariances, as the joint solve that weighs each by its noise as it is.
TEST(CalibrationFusion, WeighsEachLogByItsRowsScatter) {
  for (const std::vector<double>& scatter :
       {std::vector<double>{1.0, 3.0}, std::vector<double>{4.0, 1.0, 2.0}}) {
    const int num_logs = static_cast<int>(scatter.size());
    LinearLogs logs = MakeLogs(num_logs, 1e-3, 21 + num_logs, scatter);
    const FusedCalibration fused = FuseCalibrationPosteriors(logs.posteriors);
    ASSERT_TRUE(fused.covariance.ok);
    EXPECT_LT((TangentAtTruth(fused, logs.truth) - logs.joint_step).cwiseAbs().maxCoeff(), 1e-9)
        << num_logs;
    EXPECT_LT((fused.covariance.matrix - logs.joint_covariance).cwiseAbs().maxCoeff(),
              1e-9 * logs.joint_covariance.cwiseAbs().maxCoeff());
    // Weighed as their noise model says, the logs give other sigmas.
    for (CalibrationPosterior& log : logs.posteriors) log.widened.ok = false;
    const FusedCalibration as_stated = FuseCalibrationPosteriors(logs.posteriors);
    EXPECT_GT((as_stated.covariance.matrix - logs.joint_covariance).cwiseAbs().maxCoeff(),
              0.1 * logs.joint_covariance.cwiseAbs().maxCoeff());
  }
}

// A widening as Eq. C8 gives it, one direction's sigma doubled with its correlations kept
// (D S D, not S + S E S with E >= 0): the combination is finite and never knows more than
// it did with the log as solved.
TEST(CalibrationFusion, AWideningOfOneDirectionNeverNarrowsTheCombination) {
  LinearLogs logs = MakeLogs(2, 1.0, 13);
  const FusedCalibration as_solved = FuseCalibrationPosteriors(logs.posteriors);
  CalibrationPosterior& first = logs.posteriors[0];
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(7);
  scale(4) = 2.0;  // the lever arm's x
  first.widened.matrix = scale.asDiagonal() * first.covariance.matrix * scale.asDiagonal();
  const FusedCalibration widened = FuseCalibrationPosteriors(logs.posteriors);
  ASSERT_TRUE(widened.covariance.ok);
  ASSERT_TRUE(widened.covariance.matrix.allFinite());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> difference(widened.covariance.matrix -
                                                                  as_solved.covariance.matrix);
  EXPECT_GT(difference.eigenvalues().minCoeff(),
            -1e-12 * as_solved.covariance.matrix.cwiseAbs().maxCoeff());
  EXPECT_GT(widened.covariance.matrix(4, 4), as_solved.covariance.matrix(4, 4));
}

// The joint posterior knows more than any one log: every direction's sigma is at most the
// smallest of the logs'.
TEST(CalibrationFusion, SigmaNoLargerThanAnyLogs) {
  const LinearLogs logs = MakeLogs(3, 1.0, 3);
  const FusedCalibration fused = FuseCalibrationPosteriors(logs.posteriors);
  for (const CalibrationPosterior& log : logs.posteriors) {
    EXPECT_TRUE((fused.covariance.matrix.diagonal().array() <=
                 log.covariance.matrix.diagonal().array() * (1 + 1e-12))
                    .all());
  }
}

// A block only one log estimates is combined from that log alone.
TEST(CalibrationFusion, BlockOfOneLogKeepsItsEstimate) {
  LinearLogs logs = MakeLogs(2, 1e-3, 11);
  CalibrationPosterior& second = logs.posteriors[1];
  second.blocks.pop_back();  // the second log has no GNSS
  second.covariance.matrix = Eigen::MatrixXd(second.covariance.matrix.topLeftCorner(4, 4));
  second.covariance.offsets.pop_back();
  second.widened = second.covariance;
  const FusedCalibration fused = FuseCalibrationPosteriors(logs.posteriors);
  ASSERT_EQ(fused.blocks.size(), 3u);
  // The lever arm given the others is the first log's conditional; with the others pinned
  // harder by two logs it moves little, and its sigma is no smaller than the first log's.
  const double first_sigma = std::sqrt(logs.posteriors[0].covariance.matrix(4, 4));
  EXPECT_GE(std::sqrt(fused.covariance.matrix(4, 4)), 0.5 * first_sigma);
  EXPECT_TRUE(fused.value.p_I_A.allFinite());
}

// The prior centre of OneLog: the left radius and the antenna's lever arm, sigma 5 cm each.
sensors::Calibration OneLogPrior() {
  sensors::Calibration prior_centre;
  prior_centre.wheel_radius_left_m = 0.33;
  prior_centre.p_I_A = Eigen::Vector3d(0.1, -0.2, 1.2);
  return prior_centre;
}

// One log off the prior centre by centimetres, its sigma per direction (radius, lever arm x, y,
// z) sigma_ratio times the prior's.
CalibrationPosterior OneLog(const Eigen::Vector4d& sigma_ratio) {
  const sensors::Calibration prior_centre = OneLogPrior();
  CalibrationPosterior log;
  log.solved = prior_centre;
  log.solved.wheel_radius_left_m += 0.04;
  log.solved.p_I_A += Eigen::Vector3d(0.02, 0.03, -0.05);
  log.blocks =
      Blocks(&log.solved, {CalibrationBlockId::kWheelRadiusLeft, CalibrationBlockId::kGnssLeverArm},
             prior_centre);
  log.covariance.ok = true;
  log.covariance.offsets = {0, 1};
  log.covariance.matrix = (sigma_ratio * 0.05).array().square().matrix().asDiagonal();
  return log;
}

// A log whose covariance is wider than its prior (the data's own curvature negative, Eq. C5)
// tells nothing: the combination is the prior, not a sigma twice the prior's.
TEST(CalibrationFusion, ALogWiderThanItsPriorAddsNothing) {
  CalibrationPosterior log = OneLog(Eigen::Vector4d::Constant(2.0));
  log.covariance.matrix(0, 1) = log.covariance.matrix(1, 0) = 1e-3;
  const FusedCalibration fused = FuseCalibrationPosteriors({log});
  ASSERT_TRUE(fused.covariance.ok);
  EXPECT_LT((fused.covariance.matrix - Eigen::MatrixXd::Identity(4, 4) * 0.05 * 0.05)
                .cwiseAbs()
                .maxCoeff(),
            1e-15);
  EXPECT_NEAR(fused.value.wheel_radius_left_m, 0.33, 1e-12);
  EXPECT_LT((fused.value.p_I_A - OneLogPrior().p_I_A).norm(), 1e-12);
}

// Mixed: the radius and the antenna's y and z narrowed by the log (sigma half the prior's),
// the antenna's x widened (twice). The narrowed directions combine as usual (sigma half the
// prior's, at the log's value); the widened one is left at the prior.
TEST(CalibrationFusion, ALogAddsOnlyWhereItsDataCurveUp) {
  const CalibrationPosterior log = OneLog(Eigen::Vector4d(0.5, 2.0, 0.5, 0.5));
  const FusedCalibration fused = FuseCalibrationPosteriors({log});
  ASSERT_TRUE(fused.covariance.ok);
  const Eigen::Vector4d expected_sigma = Eigen::Vector4d(0.5, 1.0, 0.5, 0.5) * 0.05;
  EXPECT_LT((fused.covariance.matrix.diagonal().cwiseSqrt() - expected_sigma).cwiseAbs().maxCoeff(),
            1e-12);
  EXPECT_NEAR(fused.value.wheel_radius_left_m, log.solved.wheel_radius_left_m, 1e-12);
  EXPECT_NEAR(fused.value.p_I_A.x(), OneLogPrior().p_I_A.x(), 1e-12);
  EXPECT_LT((fused.value.p_I_A.tail<2>() - log.solved.p_I_A.tail<2>()).norm(), 1e-12);
}

TEST(CalibrationFusion, RefusesALogWithoutCovariance) {
  LinearLogs logs = MakeLogs(2, 1.0, 5);
  logs.posteriors[1].covariance.ok = false;
  EXPECT_THROW(FuseCalibrationPosteriors(logs.posteriors), Error);
  EXPECT_THROW(FuseCalibrationPosteriors({}), Error);
}

// Logs drawn from one truth with errors of their stated covariance (a radius and a lever arm).
std::vector<CalibrationPosterior> AgreeingLogs(int num_logs, std::mt19937* rng) {
  std::normal_distribution<double> normal;
  std::vector<CalibrationPosterior> logs;
  for (int i = 0; i < num_logs; ++i) {
    CalibrationPosterior log;
    log.blocks = Blocks(&log.solved,
                        {CalibrationBlockId::kWheelRadiusRight, CalibrationBlockId::kGnssLeverArm},
                        sensors::Calibration());
    std::uniform_real_distribution<double> uniform(-1.0, 1.0);
    Eigen::MatrixXd A(4, 4);
    for (double& a : A.reshaped()) a = uniform(*rng) * 1e-3 * (1 + i);
    log.covariance.matrix = A * A.transpose() + 1e-8 * Eigen::MatrixXd::Identity(4, 4);
    log.covariance.offsets = {0, 1};
    log.covariance.ok = true;
    const Eigen::MatrixXd L = log.covariance.matrix.llt().matrixL();
    Eigen::VectorXd e(4);
    for (int k = 0; k < 4; ++k) e(k) = normal(*rng);
    const Eigen::VectorXd error = L * e;
    log.solved.wheel_radius_right_m += error(0);
    log.solved.p_I_A += error.tail<3>();
    logs.push_back(log);
  }
  return logs;
}

// Under one truth the test's p-value is uniform: about 5 % of trials fall below 0.05.
TEST(CalibrationAgreement, PValuesUniformUnderOneTruth) {
  std::mt19937 rng(17);
  int below_5_percent = 0, below_50_percent = 0;
  const int trials = 2000;
  for (int t = 0; t < trials; ++t) {
    const std::vector<BlockAgreement> agreement = AgreementOfLogs(AgreeingLogs(3, &rng));
    ASSERT_EQ(agreement.size(), 2u);
    EXPECT_EQ(agreement[1].degrees_of_freedom, 6);
    below_5_percent += agreement[1].p_value < 0.05;
    below_50_percent += agreement[0].p_value < 0.5;
  }
  // Binomial sigma: 0.5 % and 1.1 % of the trials.
  EXPECT_NEAR(below_5_percent / static_cast<double>(trials), 0.05, 0.02);
  EXPECT_NEAR(below_50_percent / static_cast<double>(trials), 0.5, 0.05);
}

// The test weighs each log by the covariance it reports: widened 100 times, chi^2 / 100.
TEST(CalibrationAgreement, WeighsByTheReportedCovariance) {
  std::mt19937 rng(9);
  std::vector<CalibrationPosterior> logs = AgreeingLogs(3, &rng);
  const std::vector<BlockAgreement> as_solved = AgreementOfLogs(logs);
  for (CalibrationPosterior& log : logs) {
    log.widened = log.covariance;
    log.widened.matrix *= 100.0;
  }
  const std::vector<BlockAgreement> widened = AgreementOfLogs(logs);
  ASSERT_EQ(widened.size(), as_solved.size());
  for (size_t b = 0; b < widened.size(); ++b) {
    EXPECT_NEAR(widened[b].chi_square, as_solved[b].chi_square / 100.0,
                1e-9 * as_solved[b].chi_square);
    EXPECT_NEAR(widened[b].z, as_solved[b].z / 10.0, 1e-9 * as_solved[b].z);
  }
}

// A radius that changed in one log (a tyre) fails the test and is named with its pair.
TEST(CalibrationAgreement, FindsTheChangedLog) {
  std::mt19937 rng(5);
  std::vector<CalibrationPosterior> logs = AgreeingLogs(3, &rng);
  const double sigma = std::sqrt(logs[2].covariance.matrix(0, 0) + logs[0].covariance.matrix(0, 0));
  logs[2].solved.wheel_radius_right_m += 12.0 * sigma;
  const std::vector<BlockAgreement> agreement = AgreementOfLogs(logs);
  EXPECT_EQ(agreement[0].id, CalibrationBlockId::kWheelRadiusRight);
  EXPECT_LT(agreement[0].p_value, 1e-6);
  EXPECT_EQ(agreement[0].log_b, 2u);
  EXPECT_GT(agreement[0].difference, 0.0);
  EXPECT_GT(agreement[0].z, 8.0);
  EXPECT_GT(agreement[1].p_value, 1e-3);  // the lever arm still agrees
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
