#include "residual_groups.h"

#include <cmath>
#include <set>
#include <utility>

#include "autocal/factors/gnss_factor.h"
#include "autocal/factors/imu_factor.h"
#include "autocal/factors/loss.h"
#include "autocal/factors/planar_rotation_factor.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/factors/point_to_sweep_plane_factor.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "autocal/factors/wheel_factor.h"
#include "common/order_statistics.h"
#include "estimation/time_offset_factors.h"

namespace autocal {
namespace pipeline {

namespace {

// Whether `f` is a wheel factor of any form (Eqs. F22, F25, F26).
bool IsWheelCost(const ceres::CostFunction* f) {
  using SpeedCost = ceres::AutoDiffCostFunction<factors::WheelSpeedResidual, ceres::DYNAMIC, 4, 3,
                                                3, 4, 3, 1, 1, 1>;
  using TwistCost = ceres::AutoDiffCostFunction<factors::OdometryTwistResidual, ceres::DYNAMIC, 4,
                                                3, 3, 4, 3, 1, 1>;
  using ShiftedCost = estimation::internal::ShiftedWheelResidual::Cost;
  return dynamic_cast<const factors::WheelFactor*>(f) || dynamic_cast<const SpeedCost*>(f) ||
         dynamic_cast<const TwistCost*>(f) || dynamic_cast<const ShiftedCost*>(f);
}

bool IsGnssCost(const ceres::CostFunction* f) {
  using ShiftedCost = estimation::internal::ShiftedGnssResidual::Cost;
  return dynamic_cast<const factors::GnssFactor*>(f) || dynamic_cast<const ShiftedCost*>(f);
}

// The residual blocks of the IMU, wheel and GNSS factors in `problem`, by sensor.
std::map<std::string, std::vector<ceres::ResidualBlockId>> BlocksBySensor(ceres::Problem* problem) {
  std::vector<ceres::ResidualBlockId> all;
  problem->GetResidualBlocks(&all);
  std::map<std::string, std::vector<ceres::ResidualBlockId>> ids;
  for (ceres::ResidualBlockId id : all) {
    const ceres::CostFunction* f = problem->GetCostFunctionForResidualBlock(id);
    if (dynamic_cast<const factors::ImuFactor*>(f)) ids["imu"].push_back(id);
    if (IsWheelCost(f)) ids["wheel"].push_back(id);
    if (IsGnssCost(f)) ids["gnss"].push_back(id);
    if (dynamic_cast<const factors::PlanarRotationFactor*>(f)) {
      ids["planar_rotation"].push_back(id);
    }
  }
  return ids;
}

bool IsLidarCost(const ceres::CostFunction* f) {
  return dynamic_cast<const factors::PointToSweepPlaneGroupFactor*>(f) ||
         dynamic_cast<const factors::PointToSweepPlaneFactor*>(f) ||
         dynamic_cast<const factors::PointToPlaneFactor*>(f);
}

// The share ratio of `ids` (ResidualSources).
double ShareRatio(ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& ids) {
  factors::RowPull sum;
  if (const std::optional<factors::SandwichRatio> points = PointGroupDistances(problem, ids)) {
    sum = points->pull();
  }
  std::map<std::pair<const ceres::LossFunction*, int>, factors::RowPull> expected;
  for (const ceres::ResidualBlockId id : ids) {
    const ceres::CostFunction* f = problem->GetCostFunctionForResidualBlock(id);
    if (dynamic_cast<const factors::PointToSweepPlaneGroupFactor*>(f) != nullptr) continue;
    const auto key = std::make_pair(problem->GetLossFunctionForResidualBlock(id),
                                    static_cast<int>(f->num_residuals()));
    auto found = expected.find(key);
    if (found == expected.end()) {
      found = expected.emplace(key, factors::ExpectedRowPull(key.first, key.second)).first;
    }
    sum.pull_squared += found->second.pull_squared;
    sum.weight += found->second.weight;
  }
  return sum.weight > 0.0 ? sum.pull_squared / sum.weight : 1.0;
}

}  // namespace

std::optional<factors::SandwichRatio> PointGroupDistances(
    ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& ids,
    std::vector<ceres::ResidualBlockId>* groups) {
  std::optional<factors::SandwichRatio> ratio;
  std::vector<double> distances;
  std::vector<double*> parameters;
  for (const ceres::ResidualBlockId id : ids) {
    const auto* group = dynamic_cast<const factors::PointToSweepPlaneGroupFactor*>(
        problem->GetCostFunctionForResidualBlock(id));
    if (group == nullptr) continue;
    if (groups != nullptr) groups->push_back(id);
    if (!ratio) ratio.emplace(group->loss());
    problem->GetParameterBlocksForResidualBlock(id, &parameters);
    distances.resize(static_cast<size_t>(group->num_points()));
    group->WhitenedDistances(parameters.data(), distances.data());
    for (const double r : distances) ratio->Add(r);
  }
  return ratio;
}

std::vector<estimation::ResidualSource> ResidualSources(ceres::Problem* problem) {
  std::map<std::string, std::vector<ceres::ResidualBlockId>> by_sensor = BlocksBySensor(problem);
  std::vector<ceres::ResidualBlockId> all;
  problem->GetResidualBlocks(&all);
  estimation::ResidualSource lidar{"lidar", {}};
  estimation::ResidualSource priors{"priors", {}};
  std::set<ceres::ResidualBlockId> assigned;
  for (const auto& [sensor, ids] : by_sensor) assigned.insert(ids.begin(), ids.end());
  for (ceres::ResidualBlockId id : all) {
    if (assigned.count(id) > 0) continue;
    const bool is_lidar = IsLidarCost(problem->GetCostFunctionForResidualBlock(id));
    (is_lidar ? lidar : priors).residual_blocks.push_back(id);
  }
  std::vector<estimation::ResidualSource> out;
  if (!lidar.residual_blocks.empty()) out.push_back(std::move(lidar));
  for (auto& [sensor, ids] : by_sensor) out.push_back({sensor, std::move(ids)});
  if (!priors.residual_blocks.empty()) out.push_back(std::move(priors));
  for (estimation::ResidualSource& source : out) {
    source.share_ratio = ShareRatio(problem, source.residual_blocks);
  }
  return out;
}

std::map<std::string, double> WhitenedStatistics(const std::vector<double>& rows, bool alike_rows) {
  std::map<std::string, double> out;
  if (rows.empty()) return out;
  const double rows_n = static_cast<double>(rows.size());
  double sum = 0.0;
  for (double r : rows) sum += r * r;
  out["rows"] = rows_n;
  out["whitened_rms"] = std::sqrt(sum / rows_n);
  if (!alike_rows) return out;
  std::vector<double> magnitudes;
  magnitudes.reserve(rows.size());
  for (double r : rows) magnitudes.push_back(std::abs(r));
  const double robust_sigma = 1.4826 * autocal::internal::Median(magnitudes);
  double inlier_sum = 0.0;
  size_t outliers = 0;
  for (double r : rows) {
    if (std::abs(r) > kOutlierRobustSigmas * robust_sigma) {
      ++outliers;
    } else {
      inlier_sum += r * r;
    }
  }
  out["whitened_robust_sigma"] = robust_sigma;
  out["outlier_rows"] = static_cast<double>(outliers);
  out["whitened_rms_without_outliers"] =
      outliers < rows.size() ? std::sqrt(inlier_sum / (rows_n - static_cast<double>(outliers)))
                             : 0.0;
  return out;
}

void RecordResidualsAfterSolve(ceres::Problem* problem,
                               std::map<std::string, SensorResiduals>* residuals) {
  for (const auto& [sensor, blocks] : BlocksBySensor(problem)) {
    SensorResiduals& r = (*residuals)[sensor];
    r.after.clear();
    r.factors = blocks.size();
    r.factors_downweighted = 0;
    double kept_sum = 0.0;
    size_t kept_rows = 0;
    for (ceres::ResidualBlockId id : blocks) {
      const size_t first = r.after.size();
      r.after.resize(first + static_cast<size_t>(
                                 problem->GetCostFunctionForResidualBlock(id)->num_residuals()));
      double cost = 0.0;
      problem->EvaluateResidualBlock(id, false, &cost, r.after.data() + first, nullptr);
      // s = |r|^2; Ceres' cost is s / 2.
      if (factors::DownweightedByLoss(problem->GetLossFunctionForResidualBlock(id), 2.0 * cost)) {
        ++r.factors_downweighted;
        continue;
      }
      for (size_t k = first; k < r.after.size(); ++k) kept_sum += r.after[k] * r.after[k];
      kept_rows += r.after.size() - first;
    }
    r.rms_not_downweighted =
        kept_rows > 0 ? std::sqrt(kept_sum / static_cast<double>(kept_rows)) : 0.0;
  }
}

std::map<std::string, std::vector<double>> WhitenedResidualsBySensor(ceres::Problem* problem) {
  std::map<std::string, std::vector<double>> out;
  for (const auto& [sensor, blocks] : BlocksBySensor(problem)) {
    ceres::Problem::EvaluateOptions evaluate;
    evaluate.residual_blocks = blocks;
    evaluate.apply_loss_function = false;
    problem->Evaluate(evaluate, nullptr, &out[sensor], nullptr, nullptr);
  }
  return out;
}

}  // namespace pipeline
}  // namespace autocal
