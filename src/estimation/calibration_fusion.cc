#include "autocal/estimation/calibration_fusion.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <string>

#include "autocal/common/chi_square.h"
#include "autocal/common/error.h"
#include "autocal/sensors/calibration_blocks.h"

namespace autocal {
namespace estimation {
namespace {

const double* ValuesIn(const sensors::Calibration& calibration, const EstimatedBlock& block) {
  return sensors::CalibrationBlock(block.id).const_values(calibration);
}

// Every block any log estimates, in table order, as the first log that estimates it has it;
// its values are copied from that log's solve into *reference.
std::vector<EstimatedBlock> UnionOfBlocks(const std::vector<CalibrationPosterior>& logs,
                                          sensors::Calibration* reference) {
  std::vector<EstimatedBlock> blocks;
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    for (const CalibrationPosterior& log : logs) {
      const auto it = std::find_if(log.blocks.begin(), log.blocks.end(),
                                   [&](const EstimatedBlock& b) { return b.id == info.id; });
      if (it == log.blocks.end()) continue;
      std::copy_n(info.const_values(log.solved), info.ambient_size, info.values(reference));
      blocks.push_back(*it);
      break;
    }
  }
  return blocks;
}

// A block's prior as information: P = diag(sigma^-2) and P p, p its centre in the tangent at
// `reference` (Eq. M1-M2).
struct PriorTerms {
  Eigen::VectorXd information;
  Eigen::VectorXd vector;
};
PriorTerms PriorOf(const EstimatedBlock& block, const sensors::Calibration& reference) {
  PriorTerms out;
  out.information = block.prior_sigma.array().square().inverse();
  out.vector = out.information.cwiseProduct(
      BlockMinus(block, block.prior.data(), ValuesIn(reference, block)));
  return out;
}

// The row of each block of `blocks` in the union (`fused`).
std::vector<int> RowsInUnion(const std::vector<EstimatedBlock>& blocks,
                             const std::vector<EstimatedBlock>& fused,
                             const std::vector<int>& fused_offsets) {
  std::vector<int> rows;
  for (const EstimatedBlock& block : blocks) {
    for (size_t f = 0; f < fused.size(); ++f) {
      if (fused[f].id == block.id) rows.push_back(fused_offsets[f]);
    }
  }
  return rows;
}

// A log's data term, information D and vector d of 1/2 x^T D x - d^T x (D = Lambda - P,
// d = Lambda x - P p), in the prior's units (those of P^-1/2 D P^-1/2, so that the result does
// not depend on the blocks' units), made what Eq. M1-M2 add:
// - kept only along the directions where it curves up (its eigenvectors with a positive
//   eigenvalue). Where the exact Hessian (docs/calibration.md, Eq. C5) says the data curve the
//   cost down, the quadratic is only local and has no centre: the log tells nothing there, as
//   if its drive had not excited the direction.
// - weighed by its rows' scatter over the log (Eq. C8). With `inflation` E = Lambda (W - S)
//   Lambda, W the widened covariance and S the solved one, the data's centre c = D^-1 d has
//   covariance D^-1 (D + E) D^-1 rather than D^-1, so its information is
//   G = D^1/2 (I + F)^-1 D^1/2, F = D^-1/2 E D^-1/2 (no narrower than D: F's negative
//   eigenvalues, rounding or a widening that is not a matrix inequality, count as 0), and the
//   vector G c. An empty `inflation` leaves D as it is.
void MakeDataTerm(const Eigen::VectorXd& prior_information, const Eigen::MatrixXd& inflation,
                  Eigen::MatrixXd* D, Eigen::VectorXd* d) {
  const Eigen::VectorXd scale = prior_information.cwiseSqrt();  // P^1/2
  const Eigen::MatrixXd whitened = scale.cwiseInverse().asDiagonal() *
                                   (0.5 * (*D + D->transpose())) *
                                   scale.cwiseInverse().asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(whitened);
  if (eigen.eigenvalues().minCoeff() > 0.0 && inflation.size() == 0) return;
  std::vector<Eigen::Index> kept;
  for (Eigen::Index k = 0; k < whitened.rows(); ++k) {
    if (eigen.eigenvalues()(k) > 0.0) kept.push_back(k);
  }
  const auto K = static_cast<Eigen::Index>(kept.size());
  Eigen::MatrixXd U(whitened.rows(), K);
  Eigen::VectorXd root(K);  // eigenvalues^1/2
  for (Eigen::Index k = 0; k < K; ++k) {
    U.col(k) = eigen.eigenvectors().col(kept[static_cast<size_t>(k)]);
    root(k) = std::sqrt(eigen.eigenvalues()(kept[static_cast<size_t>(k)]));
  }
  Eigen::MatrixXd M = Eigen::MatrixXd::Identity(K, K);  // (I + F)^-1
  if (inflation.size() != 0 && K > 0) {
    const Eigen::MatrixXd E =
        scale.cwiseInverse().asDiagonal() * inflation * scale.cwiseInverse().asDiagonal();
    const Eigen::MatrixXd F =
        root.cwiseInverse().asDiagonal() * U.transpose() * E * U * root.cwiseInverse().asDiagonal();
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> f(0.5 * (F + F.transpose()));
    M = f.eigenvectors() *
        (1.0 + f.eigenvalues().cwiseMax(0.0).array()).inverse().matrix().asDiagonal() *
        f.eigenvectors().transpose();
  }
  const Eigen::MatrixXd A = scale.asDiagonal() * U * root.asDiagonal();  // P^1/2 U D_K^1/2
  *d = A * M * root.cwiseInverse().asDiagonal() * U.transpose() *
       scale.cwiseInverse().asDiagonal() * *d;
  *D = A * M * A.transpose();
}

// One log's terms of Eq. M1-M2, added into (information, vector) at the union's rows: its
// posterior information and its prior's removed, in the tangent at `reference`.
void AddLogTerms(const CalibrationPosterior& log, const sensors::Calibration& reference,
                 const std::vector<int>& rows, size_t index, Eigen::MatrixXd* information,
                 Eigen::VectorXd* vector) {
  const Eigen::MatrixXd& S = log.covariance.matrix;
  const Eigen::LLT<Eigen::MatrixXd> llt(S);
  if (llt.info() != Eigen::Success) {
    throw Error("log " + std::to_string(index + 1) +
                ": the covariance of its calibration is not positive definite");
  }
  const Eigen::MatrixXd posterior_information =
      llt.solve(Eigen::MatrixXd::Identity(S.rows(), S.cols()));
  Eigen::VectorXd x(S.rows()), prior_term(S.rows()), prior_information(S.rows());
  for (size_t b = 0; b < log.blocks.size(); ++b) {
    const EstimatedBlock& block = log.blocks[b];
    const int first = log.covariance.offsets[b];
    x.segment(first, block.size) =
        BlockMinus(block, ValuesIn(log.solved, block), ValuesIn(reference, block));
    const PriorTerms prior = PriorOf(block, reference);
    prior_information.segment(first, block.size) = prior.information;
    prior_term.segment(first, block.size) = prior.vector;
  }
  Eigen::MatrixXd data_information = posterior_information;
  data_information.diagonal() -= prior_information;
  Eigen::VectorXd data_vector = posterior_information * x - prior_term;
  const BlockCovariance& reported = log.Reported();
  if (reported.offsets != log.covariance.offsets || reported.matrix.rows() != S.rows() ||
      reported.matrix.cols() != S.cols()) {
    throw Error("log " + std::to_string(index + 1) +
                ": its widened covariance does not have its covariance's blocks");
  }
  const Eigen::MatrixXd inflation =
      &reported == &log.covariance || reported.matrix == S
          ? Eigen::MatrixXd()
          : Eigen::MatrixXd(posterior_information * (reported.matrix - S) * posterior_information);
  MakeDataTerm(prior_information, inflation, &data_information, &data_vector);
  for (size_t a = 0; a < log.blocks.size(); ++a) {
    for (size_t b = 0; b < log.blocks.size(); ++b) {
      information->block(rows[a], rows[b], log.blocks[a].size, log.blocks[b].size) +=
          data_information.block(log.covariance.offsets[a], log.covariance.offsets[b],
                                 log.blocks[a].size, log.blocks[b].size);
    }
    vector->segment(rows[a], log.blocks[a].size) +=
        data_vector.segment(log.covariance.offsets[a], log.blocks[a].size);
  }
}

}  // namespace

void BindBlocks(sensors::Calibration* calibration, std::vector<EstimatedBlock>* blocks) {
  for (EstimatedBlock& block : *blocks) {
    block.data = sensors::CalibrationBlock(block.id).values(calibration);
  }
}

FusedCalibration FuseCalibrationPosteriors(const std::vector<CalibrationPosterior>& logs) {
  if (logs.empty()) throw Error("no log to combine");
  for (size_t i = 0; i < logs.size(); ++i) {
    if (!logs[i].covariance.ok) {
      throw Error("log " + std::to_string(i + 1) +
                  " has no covariance of its calibration, so it cannot be combined");
    }
  }
  FusedCalibration out;
  out.value = logs.front().solved;
  out.blocks = UnionOfBlocks(logs, &out.value);
  int n = 0;
  for (const EstimatedBlock& block : out.blocks) {
    out.covariance.offsets.push_back(n);
    n += block.size;
  }
  const sensors::Calibration reference = out.value;
  // The one prior (Eq. M1-M2's P and p): the first log's of each block.
  Eigen::MatrixXd information = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd vector = Eigen::VectorXd::Zero(n);
  for (size_t b = 0; b < out.blocks.size(); ++b) {
    const EstimatedBlock& block = out.blocks[b];
    const int first = out.covariance.offsets[b];
    const PriorTerms prior = PriorOf(block, reference);
    information.diagonal().segment(first, block.size) += prior.information;
    vector.segment(first, block.size) += prior.vector;
  }
  for (size_t i = 0; i < logs.size(); ++i) {
    AddLogTerms(logs[i], reference, RowsInUnion(logs[i].blocks, out.blocks, out.covariance.offsets),
                i, &information, &vector);
  }
  const Eigen::LLT<Eigen::MatrixXd> llt(0.5 * (information + information.transpose()));
  if (llt.info() != Eigen::Success) {
    throw Error(
        "the logs' information on the calibration does not combine into a positive "
        "definite one");
  }
  out.covariance.matrix = llt.solve(Eigen::MatrixXd::Identity(n, n));
  out.covariance.matrix = 0.5 * (out.covariance.matrix + out.covariance.matrix.transpose());
  out.covariance.ok = out.covariance.matrix.allFinite();
  const Eigen::VectorXd step = llt.solve(vector);
  BindBlocks(&out.value, &out.blocks);
  for (size_t b = 0; b < out.blocks.size(); ++b) {
    BlockPlus(out.blocks[b], step.segment(out.covariance.offsets[b], out.blocks[b].size),
              out.blocks[b].data);
  }
  return out;
}

namespace {

// Log i's estimate of one block and its marginal covariance.
struct BlockEstimate {
  size_t log = 0;
  const EstimatedBlock* block = nullptr;
  const double* values = nullptr;
  Eigen::MatrixXd covariance;
};

std::vector<BlockEstimate> EstimatesOf(sensors::CalibrationBlockId id,
                                       const std::vector<CalibrationPosterior>& logs) {
  std::vector<BlockEstimate> estimates;
  for (size_t i = 0; i < logs.size(); ++i) {
    for (size_t b = 0; b < logs[i].blocks.size(); ++b) {
      const EstimatedBlock& block = logs[i].blocks[b];
      if (block.id != id) continue;
      const int first = logs[i].covariance.offsets[b];
      estimates.push_back({i, &block, ValuesIn(logs[i].solved, block),
                           logs[i].Reported().matrix.block(first, first, block.size, block.size)});
    }
  }
  return estimates;
}

BlockAgreement Agreement(sensors::CalibrationBlockId id,
                         const std::vector<BlockEstimate>& estimates) {
  BlockAgreement out;
  out.id = id;
  const EstimatedBlock& block = *estimates.front().block;
  const double* reference = estimates.front().values;
  const int d = block.size;
  Eigen::MatrixXd weight_sum = Eigen::MatrixXd::Zero(d, d);
  Eigen::VectorXd weighted = Eigen::VectorXd::Zero(d);
  std::vector<Eigen::VectorXd> x;
  std::vector<Eigen::MatrixXd> weights;
  for (const BlockEstimate& e : estimates) {
    out.logs.push_back(e.log);
    x.push_back(BlockMinus(block, e.values, reference));
    weights.push_back(e.covariance.ldlt().solve(Eigen::MatrixXd::Identity(d, d)));
    weight_sum += weights.back();
    weighted += weights.back() * x.back();
  }
  const Eigen::VectorXd mean = weight_sum.ldlt().solve(weighted);
  for (size_t i = 0; i < x.size(); ++i) {
    out.chi_square += (x[i] - mean).dot(weights[i] * (x[i] - mean));
  }
  out.degrees_of_freedom = static_cast<int>(x.size() - 1) * d;
  out.p_value = ChiSquareUpperTail(out.chi_square, out.degrees_of_freedom);
  for (size_t a = 0; a < x.size(); ++a) {
    for (size_t b = a + 1; b < x.size(); ++b) {
      const Eigen::VectorXd difference =
          BlockMinus(block, estimates[b].values, estimates[a].values);
      for (int k = 0; k < d; ++k) {
        const double sigma =
            std::sqrt(estimates[a].covariance(k, k) + estimates[b].covariance(k, k));
        const double z = std::abs(difference(k)) / sigma;
        if (z <= out.z) continue;
        out.z = z;
        out.log_a = estimates[a].log;
        out.log_b = estimates[b].log;
        out.direction = k;
        out.difference = difference(k);
      }
    }
  }
  return out;
}

}  // namespace

std::vector<BlockAgreement> AgreementOfLogs(const std::vector<CalibrationPosterior>& logs) {
  for (size_t i = 0; i < logs.size(); ++i) {
    if (!logs[i].covariance.ok) {
      throw Error("log " + std::to_string(i + 1) + " has no covariance of its calibration");
    }
    const BlockCovariance& reported = logs[i].Reported();
    if (reported.offsets != logs[i].covariance.offsets ||
        reported.matrix.rows() != logs[i].covariance.matrix.rows()) {
      throw Error("log " + std::to_string(i + 1) +
                  ": its widened covariance does not have its covariance's blocks");
    }
  }
  std::vector<BlockAgreement> out;
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    const std::vector<BlockEstimate> estimates = EstimatesOf(info.id, logs);
    if (estimates.size() >= 2) out.push_back(Agreement(info.id, estimates));
  }
  return out;
}

}  // namespace estimation
}  // namespace autocal
