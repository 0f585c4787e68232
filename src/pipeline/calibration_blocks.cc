#include "calibration_blocks.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "autocal/factors/prior_factors.h"
#include "autocal/geometry/quaternion_plus.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace pipeline {

namespace {

Eigen::Quaterniond AsQuaternion(const double* xyzw) {
  return Eigen::Quaterniond(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
}

// x - x0 in the block's tangent.
Eigen::VectorXd TangentFromPrior(const CalibrationBlock& block) {
  if (block.rotation) {
    const Eigen::Quaterniond q0 = AsQuaternion(block.prior.data());
    const Eigen::Quaterniond q = AsQuaternion(block.data);
    return geometry::Log(Eigen::Quaterniond(q0.conjugate() * q));
  }
  return Eigen::Map<const Eigen::VectorXd>(block.data, block.size) - block.prior;
}

// Direction i of a block is informed by the drive (not held at its prior) when its posterior
// sigma is well below its prior's and within a few times its limit.
bool Informed(const CalibrationBlock& block, int i, double posterior_sigma) {
  return posterior_sigma <= block.max_posterior_to_prior_sigma * block.prior_sigma(i) &&
         posterior_sigma <= block.max_kept_sigma_to_limit * block.max_observable_sigma;
}

// Direction i of a block is excited when it is informed and its sigma within the limit.
bool Excited(const CalibrationBlock& block, int i, double posterior_sigma) {
  return Informed(block, i, posterior_sigma) && posterior_sigma <= block.max_observable_sigma;
}

void Step(const CalibrationBlock& block, const Eigen::VectorXd& step) {
  if (block.rotation) {
    Eigen::Map<Eigen::Quaterniond> q(block.data);
    q = geometry::QuaternionPlus(Eigen::Quaterniond(q), Eigen::Vector3d(step));
    return;
  }
  Eigen::Map<Eigen::VectorXd>(block.data, block.size) += step;
}

}  // namespace

void AddBlockPriors(const std::vector<CalibrationBlock>& blocks, const factors::LossOptions& loss,
                    ceres::Problem* problem) {
  for (const CalibrationBlock& block : blocks) {
    const Eigen::MatrixXd sqrt_information = factors::SqrtInformationFromSigmas(block.prior_sigma);
    ceres::CostFunction* cost =
        block.rotation
            ? static_cast<ceres::CostFunction*>(new factors::QuaternionPriorFactor(
                  AsQuaternion(block.prior.data()), sqrt_information))
            : new factors::VectorPriorFactor(block.prior, sqrt_information);
    problem->AddResidualBlock(cost, factors::MakeLossFunction(loss), block.data);
  }
}

BlockCovariance ComputeBlockCovariance(const std::vector<CalibrationBlock>& blocks,
                                       ceres::Problem* problem) {
  BlockCovariance out;
  int size = 0;
  for (const CalibrationBlock& block : blocks) {
    out.offsets.push_back(size);
    size += block.size;
  }
  out.matrix = Eigen::MatrixXd::Zero(size, size);
  if (blocks.empty()) {
    out.ok = true;
    return out;
  }
  std::vector<std::pair<const double*, const double*>> pairs;
  for (size_t a = 0; a < blocks.size(); ++a) {
    for (size_t b = a; b < blocks.size(); ++b) pairs.emplace_back(blocks[a].data, blocks[b].data);
  }
  ceres::Covariance::Options options;
  options.algorithm_type = ceres::SPARSE_QR;
  ceres::Covariance covariance(options);
  if (!covariance.Compute(pairs, problem)) return out;
  for (size_t a = 0; a < blocks.size(); ++a) {
    for (size_t b = a; b < blocks.size(); ++b) {
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> c(blocks[a].size,
                                                                                blocks[b].size);
      if (!covariance.GetCovarianceBlockInTangentSpace(blocks[a].data, blocks[b].data,
                                                       c.data())) {
        return out;
      }
      out.matrix.block(out.offsets[a], out.offsets[b], blocks[a].size, blocks[b].size) = c;
      out.matrix.block(out.offsets[b], out.offsets[a], blocks[b].size, blocks[a].size) =
          c.transpose();
    }
  }
  out.ok = out.matrix.allFinite();
  return out;
}

std::vector<std::string> ImplausibleDirections(const std::vector<CalibrationBlock>& blocks,
                                               const BlockCovariance& covariance,
                                               double max_sigmas) {
  std::vector<std::string> out;
  for (size_t b = 0; b < blocks.size(); ++b) {
    const CalibrationBlock& block = blocks[b];
    const Eigen::VectorXd difference = TangentFromPrior(block);
    for (int i = 0; i < block.size; ++i) {
      if (covariance.ok) {
        const int row = covariance.offsets[b] + i;
        if (!Excited(block, i, std::sqrt(std::max(0.0, covariance.matrix(row, row))))) continue;
      }
      const double sigmas = std::abs(difference(i)) / block.prior_sigma(i);
      if (!(sigmas <= max_sigmas)) {  // also catches NaN
        std::ostringstream text;
        text << std::setprecision(3) << block.direction_names[static_cast<size_t>(i)]
             << " moved " << difference(i) * block.display_scale << ' ' << block.display_unit
             << " from the nominal value, " << sigmas << " prior sigmas";
        out.push_back(text.str());
      }
    }
  }
  return out;
}

BlockObservability HoldUnobservableDirections(const std::vector<CalibrationBlock>& blocks,
                                              const BlockCovariance& covariance) {
  const Eigen::MatrixXd& S = covariance.matrix;
  const auto n = static_cast<int>(S.rows());
  Eigen::VectorXd difference(n);
  // Held (U): the drive left them at their prior; the rest (O) is conditioned on them.
  std::vector<int> observable, unobservable;
  for (size_t b = 0; b < blocks.size(); ++b) {
    const int first = covariance.offsets[b];
    difference.segment(first, blocks[b].size) = TangentFromPrior(blocks[b]);
    for (int i = 0; i < blocks[b].size; ++i) {
      const double sigma = std::sqrt(std::max(0.0, S(first + i, first + i)));
      (Informed(blocks[b], i, sigma) ? observable : unobservable).push_back(first + i);
    }
  }
  Eigen::MatrixXd conditioned = S;
  Eigen::VectorXd step = Eigen::VectorXd::Zero(n);
  if (!unobservable.empty()) {
    const auto pick = [&](const std::vector<int>& rows, const std::vector<int>& cols) {
      Eigen::MatrixXd m(rows.size(), cols.size());
      for (size_t r = 0; r < rows.size(); ++r) {
        for (size_t c = 0; c < cols.size(); ++c) {
          m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = S(rows[r], cols[c]);
        }
      }
      return m;
    };
    const Eigen::MatrixXd S_ou = pick(observable, unobservable);
    const Eigen::LDLT<Eigen::MatrixXd> S_uu(pick(unobservable, unobservable));
    Eigen::VectorXd d_u(unobservable.size()), prior_variance_u(unobservable.size());
    for (size_t u = 0; u < unobservable.size(); ++u) {
      d_u(static_cast<Eigen::Index>(u)) = difference(unobservable[u]);
      for (size_t b = 0; b < blocks.size(); ++b) {
        const int i = unobservable[u] - covariance.offsets[b];
        if (i >= 0 && i < blocks[b].size) {
          prior_variance_u(static_cast<Eigen::Index>(u)) =
              blocks[b].prior_sigma(i) * blocks[b].prior_sigma(i);
        }
      }
    }
    // Eq. C1, and Eq. C2: the held values are the nominal ones, whose own error has the prior
    // covariance P_U; through the gain K = S_OU S_UU^-1 it reaches the conditioned
    // directions, so their covariance is S_OO - K S_UO + K P_U K^T.
    const Eigen::MatrixXd gain = S_uu.solve(S_ou.transpose()).transpose();
    const Eigen::VectorXd shift = -gain * d_u;
    const Eigen::MatrixXd reduction = gain * S_ou.transpose() -
                                      gain * prior_variance_u.asDiagonal() * gain.transpose();
    for (size_t o = 0; o < observable.size(); ++o) {
      step(observable[o]) = shift(static_cast<Eigen::Index>(o));
      for (size_t o2 = 0; o2 < observable.size(); ++o2) {
        conditioned(observable[o], observable[o2]) -=
            reduction(static_cast<Eigen::Index>(o), static_cast<Eigen::Index>(o2));
      }
    }
    for (int u : unobservable) step(u) = -difference(u);
  }

  BlockObservability out;
  for (size_t b = 0; b < blocks.size(); ++b) {
    const CalibrationBlock& block = blocks[b];
    const int first = covariance.offsets[b];
    Step(block, step.segment(first, block.size));
    Eigen::VectorXd sigma =
        conditioned.diagonal().segment(first, block.size).cwiseMax(0.0).cwiseSqrt();
    std::vector<bool> flags(static_cast<size_t>(block.size), true);
    const auto value = [&](double x) {
      std::ostringstream v;
      v << std::setprecision(3) << x * block.display_scale << ' ' << block.display_unit;
      return v.str();
    };
    for (int i = 0; i < block.size; ++i) {
      const std::string& name = block.direction_names[static_cast<size_t>(i)];
      const bool held =
          std::find(unobservable.begin(), unobservable.end(), first + i) != unobservable.end();
      if (held) {
        flags[static_cast<size_t>(i)] = false;
        sigma(i) = block.prior_sigma(i);
        out.warnings.push_back(name + ": not excited by the drive (sigma " +
                               value(std::sqrt(std::max(0.0, S(first + i, first + i)))) +
                               " after the solve, prior " + value(block.prior_sigma(i)) +
                               "); held at the nominal value");
      } else if (!(sigma(i) <= block.max_observable_sigma)) {
        // Informed, but not to the accuracy asked for: the estimate is kept (it is better
        // than the nominal value) with its sigma, and not reported as observable.
        flags[static_cast<size_t>(i)] = false;
        out.warnings.push_back(name + ": only partly determined by the drive (sigma " +
                               value(sigma(i)) + ", limit " + value(block.max_observable_sigma) +
                               "); the estimate is kept and not reported as observable");
      }
    }
    out.observable.push_back(flags);
    out.sigma.push_back(sigma);
  }
  return out;
}

}  // namespace pipeline
}  // namespace autocal
