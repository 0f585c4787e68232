// Is the reported uncertainty true? The offline calibration of 20 simulated urban drives
// (different seeds: trajectories, noise, outliers), each compared with its ground truth: for
// every component the calibration calls observable, the squared error over the reported
// variance, z^2 = e^2 / sigma^2, is chi^2(1) when the sigmas are right. The average over all
// drives and components (the normalized estimation error squared per degree of freedom,
// ANEES) must lie in the two-sided 95 % band of chi^2(n) / n. The band treats the components
// as independent; components of one drive are correlated, which widens the true spread, so
// a result just outside the band is weak evidence, while the per-component figures printed
// show where a large excess comes from. Each component's own ANEES must lie in its band too,
// widened so that all of them together hold at 95 % (Bonferroni), over three drives or more.
// Drives that cannot be calibrated (the pipeline refuses them) carry no sample. Label "long":
// about 15 minutes, run with `ctest -L long`.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/evaluation/information_bound.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/dataset.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sensors/calibration_blocks.h"
#include "autocal/sim/simulator.h"
#include "support/consistency.h"
#include "support/test_paths.h"

namespace autocal {
namespace {

constexpr int kSeeds = 20;

// Normalized squared errors per component name, one entry per drive that observed it.
using Samples = std::map<std::string, std::vector<double>>;

void AddIfObservable(const std::string& name, double error, const std::optional<double>& sigma,
                     bool observable, Samples* samples) {
  if (!observable || !sigma || !(*sigma > 0.0)) return;
  (*samples)[name].push_back(error * error / (*sigma * *sigma));
}

bool Flag(const std::vector<bool>& flags, size_t index) {
  if (flags.empty()) return true;
  return flags.size() == 1 ? flags[0] : flags[index];
}

void AddPoseBlock(const std::string& name, const Eigen::Quaterniond& q_estimate,
                  const Eigen::Quaterniond& q_truth, const Eigen::Vector3d& p_estimate,
                  const Eigen::Vector3d& p_truth, const io::PoseBlockInfo& info, Samples* samples) {
  // The sigmas are of the right perturbation at the estimate: q_truth = q_estimate Exp(delta).
  const Eigen::Vector3d delta_deg = geometry::Log(q_estimate.conjugate() * q_truth) * kRadToDeg;
  const char* axes[] = {"x", "y", "z"};
  for (size_t a = 0; a < 3; ++a) {
    if (info.sigma_rot_deg) {
      AddIfObservable(name + " rotation " + axes[a], delta_deg(a), (*info.sigma_rot_deg)(a),
                      Flag(info.observable, a), samples);
    }
    if (info.sigma_p_m) {
      AddIfObservable(name + " translation " + axes[a], p_estimate(a) - p_truth(a),
                      (*info.sigma_p_m)(a), Flag(info.observable, 3 + a), samples);
    }
  }
}

// The solve's error in each direction of the posterior's blocks over the bound's sigma, for
// the directions the data inform (bound below half the prior's sigma): per direction name,
// e / sigma_bound (e = truth - estimate, OfflineCalibrationResult::error_at_bound).
void AddBoundRatios(const pipeline::OfflineCalibrationResult& result, Samples* ratios) {
  const estimation::CalibrationPosterior& posterior = result.posterior;
  if (!result.bound || !posterior.covariance.ok) return;
  for (size_t b = 0; b < posterior.blocks.size(); ++b) {
    const estimation::EstimatedBlock& block = posterior.blocks[b];
    for (int i = 0; i < block.size; ++i) {
      const int row = result.bound->offsets[b] + i;
      const double sigma = std::sqrt(result.bound->matrix(row, row));
      if (!(sigma > 0.0) || !(sigma < 0.5 * block.prior_sigma(i))) continue;
      (*ratios)[block.direction_names[static_cast<size_t>(i)]].push_back(
          result.error_at_bound(row) / sigma);
    }
  }
}

TEST(CalibrationConsistency, NormalizedErrorsMatchTheReportedSigmas) {
  Samples samples;
  Samples bound_ratios;  // e / sigma_bound per direction, one per drive
  int calibrated = 0;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    sim::SimulationOptions options;
    options.scenario = sim::ScenarioType::kUrban;
    options.duration_s = 40.0;
    options.seed = static_cast<uint64_t>(seed);
    options.lidar.config.num_beams = 16;
    const sim::Simulator simulator(options);
    // Concurrent runs of the suite each write their own copies.
    const std::string directory = test::OutputDir("urban_seed_" + std::to_string(seed) + "_" +
                                                  std::to_string(static_cast<long>(getpid())))
                                      .string();
    std::filesystem::remove_all(directory);
    sim::WriteDataset(simulator, directory);
    io::Problem problem;
    problem.path = "urban_full (consistency test)";
    problem.solver.num_threads = 2;
    pipeline::OfflineCalibrationResult result;
    try {
      const io::Dataset dataset = io::ReadDataset(directory);
      pipeline::OfflineCalibrationOptions calibration_options;
      calibration_options.set_to_truth = evaluation::TruthSetter(dataset);
      result = pipeline::CalibrateDataset(dataset, problem, calibration_options);
    } catch (const Error& e) {
      // A drive that cannot be calibrated says so; it carries no sample.
      std::cout << "seed " << seed << ": not calibrated: " << e.what() << "\n";
      std::filesystem::remove_all(directory);
      continue;
    }
    std::filesystem::remove_all(directory);
    ++calibrated;
    const sensors::Calibration& truth = simulator.true_calibration();
    const sensors::Calibration& estimate = result.calibration.value;
    const io::CalibrationUncertainty& u = result.calibration.uncertainty;
    AddBoundRatios(result, &bound_ratios);
    Samples drive;  // this drive's normalized errors, merged into `samples` below
    AddPoseBlock("T_I_L", estimate.q_I_L, truth.q_I_L, estimate.p_I_L, truth.p_I_L, u.T_I_L,
                 &drive);
    AddPoseBlock("T_I_V", estimate.q_I_V, truth.q_I_V, estimate.p_I_V, truth.p_I_V, u.T_I_V,
                 &drive);
    AddIfObservable("time offset", estimate.time_offset_lidar_imu_s - truth.time_offset_lidar_imu_s,
                    u.time_offset_lidar_imu_s.sigma,
                    u.time_offset_lidar_imu_s.observable.value_or(true), &drive);
    AddIfObservable("wheel radius left", estimate.wheel_radius_left_m - truth.wheel_radius_left_m,
                    u.wheel_radius_left_m.sigma, u.wheel_radius_left_m.observable.value_or(true),
                    &drive);
    AddIfObservable(
        "wheel radius right", estimate.wheel_radius_right_m - truth.wheel_radius_right_m,
        u.wheel_radius_right_m.sigma, u.wheel_radius_right_m.observable.value_or(true), &drive);
    AddIfObservable("track width", estimate.track_width_m - truth.track_width_m,
                    u.track_width_m.sigma, u.track_width_m.observable.value_or(true), &drive);
    if (u.p_I_A_m.sigma) {
      const char* axes[] = {"x", "y", "z"};
      for (size_t a = 0; a < 3; ++a) {
        AddIfObservable(std::string("lever arm ") + axes[a], estimate.p_I_A(a) - truth.p_I_A(a),
                        (*u.p_I_A_m.sigma)(a), Flag(u.p_I_A_m.observable, a), &drive);
      }
    }
    // The largest normalized error of this drive, to find one that breaks the average.
    double largest = 0.0;
    std::string largest_name;
    for (const auto& [name, z2] : drive) {
      for (double v : z2) {
        if (v > largest) {
          largest = v;
          largest_name = name;
        }
        samples[name].push_back(v);
      }
    }
    std::cout << "seed " << seed << ": largest z^2 " << largest << " (" << largest_name << ")"
              << std::endl;
  }
  ASSERT_GE(calibrated, 15) << "too few drives calibrated for a consistency statement";

  double sum = 0.0;
  int count = 0;
  // Each component in its own band, at 95 % for all of them together (Bonferroni).
  const double component_z =
      test::TwoSidedNormalQuantile(0.05 / static_cast<double>(samples.size()));
  std::cout << std::fixed << std::setprecision(2) << "component: ANEES (drives) [band]\n";
  for (const auto& [name, z2] : samples) {
    double component_sum = 0.0;
    for (double v : z2) component_sum += v;
    const double component_anees = component_sum / static_cast<double>(z2.size());
    const auto [component_low, component_high] =
        test::ChiSquareBandPerDof(static_cast<int>(z2.size()), component_z);
    std::cout << "  " << name << ": " << component_anees << " (" << z2.size() << ") ["
              << component_low << ", " << component_high << "]\n";
    if (z2.size() >= 3) {  // fewer draws have no lower band at this level
      EXPECT_GT(component_anees, component_low) << name << ": its sigma is too large";
      EXPECT_LT(component_anees, component_high) << name << ": its sigma is too small";
    }
    sum += component_sum;
    count += static_cast<int>(z2.size());
  }
  ASSERT_GT(count, 0);
  const double anees = sum / count;
  const auto [low, high] = test::ChiSquareBandPerDof(count);
  std::cout << "ANEES " << anees << " over " << count << " normalized errors of " << calibrated
            << " drives; 95 % band [" << low << ", " << high << "]\n";
  RecordProperty("anees", std::to_string(anees));
  RecordProperty("drives", calibrated);
  EXPECT_GT(anees, low) << "the reported sigmas are too large (pessimistic)";
  EXPECT_LT(anees, high) << "the reported sigmas are too small (overconfident)";

  // Against the Cramer-Rao bound: the RMS of e / sigma_bound over the drives, per direction
  // the data inform, is 1 for an efficient estimator (95 % of 20 draws of an efficient one
  // stay below 1.27); the goal is 1.5.
  std::cout << "direction: RMS and mean of error / Cramer-Rao bound (drives)\n";
  for (const auto& [name, ratio] : bound_ratios) {
    double sum = 0.0, sum_squares = 0.0;
    for (double r : ratio) {
      sum += r;
      sum_squares += r * r;
    }
    const double n = static_cast<double>(ratio.size());
    const double rms = std::sqrt(sum_squares / n);
    std::cout << "  " << name << ": " << rms << ", mean " << sum / n << " (" << ratio.size()
              << ")\n";
    if (ratio.size() >= 10) {
      EXPECT_LT(rms, 1.5) << name;
    }
  }
}

}  // namespace
}  // namespace autocal
