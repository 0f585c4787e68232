#pragma once

// Is the reported uncertainty true? The statistics the consistency suites share: per
// calibrated direction, z = |estimate - truth| / reported sigma over many simulated drives,
// split by how each drive reported the direction, and the normalized estimation error squared
// (NEES, the mean of z^2) against the two-sided 95 % band of chi^2(n) / n for its n drives.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"

namespace autocal {
namespace test {

// Two-sided 95 % band of chi^2(n) / n by the Wilson-Hilferty approximation (within a few
// percent of the exact quantiles for n >= 3, a fraction of a percent for n >= 10); another
// two-sided normal quantile z gives that level's band.
inline std::pair<double, double> ChiSquareBandPerDof(int n, double z = 1.959964) {
  const double c = 2.0 / (9.0 * n);
  const auto bound = [&](double zz) { return std::pow(1.0 - c + zz * std::sqrt(c), 3); };
  return {bound(-z), bound(z)};
}

// The two-sided standard normal quantile: z with P(|N(0,1)| > z) = p (bisection).
inline double TwoSidedNormalQuantile(double p) {
  double low = 0.0, high = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (low + high);
    (std::erfc(mid / std::sqrt(2.0)) > p ? low : high) = mid;
  }
  return 0.5 * (low + high);
}

// Per direction, over the drives: z of each way a drive reported it. Observable: the posterior
// sigma within its limit; kept: the estimate with its posterior sigma, not reported
// observable; held: set to the nominal value and reported with the prior sigma.
struct ConsistencySamples {
  std::vector<double> observable_z, kept_z, held_z;
  double worst_held_z = 0.0;
  int worst_held_seed = 0;
};
using ConsistencyComponents = std::map<std::string, ConsistencySamples>;

// `error` = estimate - truth and `from_nominal` = estimate - the prior's centre (where a held
// direction is held) in the direction.
inline void AddConsistencySample(const std::string& name, double error, double from_nominal,
                                 const std::optional<double>& sigma, bool observable, int seed,
                                 ConsistencyComponents* components) {
  if (!sigma) return;  // not estimated
  if (!std::isfinite(*sigma) || !(*sigma > 0.0)) {
    ADD_FAILURE() << name << " (seed " << seed << "): estimated with a sigma of " << *sigma;
    return;
  }
  ConsistencySamples& c = (*components)[name];
  const double z = std::abs(error) / *sigma;
  if (observable) {
    c.observable_z.push_back(z);
  } else if (std::abs(from_nominal) > 1e-3 * *sigma) {
    c.kept_z.push_back(z);
  } else {  // held directions sit at the nominal value to within 1e-6 of their sigma
    c.held_z.push_back(z);
    if (z > c.worst_held_z) {
      c.worst_held_z = z;
      c.worst_held_seed = seed;
    }
  }
}

inline bool ObservableFlag(const std::vector<bool>& flags, size_t index) {
  if (flags.empty()) return true;
  return flags.size() == 1 ? flags[0] : flags[index];
}

// Every calibrated direction of one drive against its truth; blocks without a reported sigma
// (not estimated) carry no sample. Rotation sigmas are of the right perturbation at the
// estimate, q_truth = q_estimate Exp(delta).
inline void AddDriveConsistency(const pipeline::OfflineCalibrationResult& result,
                                const sensors::Calibration& truth, int seed,
                                ConsistencyComponents* components) {
  const sensors::Calibration& estimate = result.calibration.value;
  const sensors::Calibration& nominal = result.prior_centre;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  const auto rotation = [&](const std::string& block, const Eigen::Quaterniond& q_estimate,
                            const Eigen::Quaterniond& q_truth, const Eigen::Quaterniond& q_nominal,
                            const io::PoseBlockInfo& pose) {
    if (!pose.sigma_rot_deg) return;
    const Eigen::Vector3d error_deg = -geometry::Log(q_estimate.conjugate() * q_truth) * kRadToDeg;
    const Eigen::Vector3d from_nominal_deg =
        geometry::Log(q_nominal.conjugate() * q_estimate) * kRadToDeg;
    const char* angles[] = {"roll", "pitch", "yaw"};
    for (size_t a = 0; a < 3; ++a) {
      AddConsistencySample(block + " " + angles[a], error_deg(a), from_nominal_deg(a),
                           (*pose.sigma_rot_deg)(a), ObservableFlag(pose.observable, a), seed,
                           components);
    }
  };
  rotation("q_I_L", estimate.q_I_L, truth.q_I_L, nominal.q_I_L, u.T_I_L);
  rotation("q_I_V", estimate.q_I_V, truth.q_I_V, nominal.q_I_V, u.T_I_V);
  const char* axes[] = {"x", "y", "z"};
  for (size_t a = 0; a < 3; ++a) {
    if (u.T_I_L.sigma_p_m) {
      AddConsistencySample(std::string("p_I_L ") + axes[a], estimate.p_I_L(a) - truth.p_I_L(a),
                           estimate.p_I_L(a) - nominal.p_I_L(a), (*u.T_I_L.sigma_p_m)(a),
                           ObservableFlag(u.T_I_L.observable, 3 + a), seed, components);
    }
    if (u.T_I_V.sigma_p_m) {
      AddConsistencySample(std::string("p_I_V ") + axes[a], estimate.p_I_V(a) - truth.p_I_V(a),
                           estimate.p_I_V(a) - nominal.p_I_V(a), (*u.T_I_V.sigma_p_m)(a),
                           ObservableFlag(u.T_I_V.observable, 3 + a), seed, components);
    }
    if (u.p_I_A_m.sigma) {
      AddConsistencySample(std::string("lever arm ") + axes[a], estimate.p_I_A(a) - truth.p_I_A(a),
                           estimate.p_I_A(a) - nominal.p_I_A(a), (*u.p_I_A_m.sigma)(a),
                           ObservableFlag(u.p_I_A_m.observable, a), seed, components);
    }
  }
  AddConsistencySample("LiDAR time offset",
                       estimate.time_offset_lidar_imu_s - truth.time_offset_lidar_imu_s,
                       estimate.time_offset_lidar_imu_s - nominal.time_offset_lidar_imu_s,
                       u.time_offset_lidar_imu_s.sigma,
                       u.time_offset_lidar_imu_s.observable.value_or(true), seed, components);
  AddConsistencySample(
      "wheel radius left", estimate.wheel_radius_left_m - truth.wheel_radius_left_m,
      estimate.wheel_radius_left_m - nominal.wheel_radius_left_m, u.wheel_radius_left_m.sigma,
      u.wheel_radius_left_m.observable.value_or(true), seed, components);
  AddConsistencySample(
      "wheel radius right", estimate.wheel_radius_right_m - truth.wheel_radius_right_m,
      estimate.wheel_radius_right_m - nominal.wheel_radius_right_m, u.wheel_radius_right_m.sigma,
      u.wheel_radius_right_m.observable.value_or(true), seed, components);
  AddConsistencySample("track width", estimate.track_width_m - truth.track_width_m,
                       estimate.track_width_m - nominal.track_width_m, u.track_width_m.sigma,
                       u.track_width_m.observable.value_or(true), seed, components);
}

// Prints a rotation block's error (roll, pitch, yaw: the right perturbation at the estimate,
// as its sigmas) against the truth, when the block was estimated.
inline void PrintRotationError(const std::string& block, int seed,
                               const Eigen::Quaterniond& q_estimate,
                               const Eigen::Quaterniond& q_truth,
                               const std::optional<Eigen::Vector3d>& sigma_deg) {
  if (!sigma_deg) return;
  const Eigen::Vector3d error_deg = -geometry::Log(q_estimate.conjugate() * q_truth) * kRadToDeg;
  std::cout << std::setprecision(3) << "seed " << seed << ": " << block
            << " error (roll, pitch, yaw) " << error_deg.transpose() << " deg, sigma "
            << sigma_deg->transpose() << " deg" << std::endl;
}

// Calibrates one drive and adds its directions; false when it cannot be calibrated (it says
// so, and carries no sample).
inline bool CalibrateAndAddDrive(const io::Dataset& dataset, const io::Problem& problem,
                                 const sensors::Calibration& truth, int seed,
                                 ConsistencyComponents* components) {
  pipeline::OfflineCalibrationResult result;
  try {
    result = pipeline::CalibrateDataset(dataset, problem);
  } catch (const Error& e) {
    std::cout << "seed " << seed << ": not calibrated: " << e.what() << "\n";
    return false;
  }
  const sensors::Calibration& estimate = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  PrintRotationError("q_I_L", seed, estimate.q_I_L, truth.q_I_L, u.T_I_L.sigma_rot_deg);
  PrintRotationError("q_I_V", seed, estimate.q_I_V, truth.q_I_V, u.T_I_V.sigma_rot_deg);
  AddDriveConsistency(result, truth, seed, components);
  return true;
}

// The NEES of one report kind of one direction and its 95 % band.
struct Nees {
  std::string kind;
  size_t drives = 0;
  double nees = 0.0, low = 0.0, high = 0.0, worst_z = 0.0;
};

inline Nees NeesOf(const std::string& kind, const std::vector<double>& z) {
  Nees out;
  out.kind = kind;
  out.drives = z.size();
  if (z.empty()) return out;
  double sum = 0.0;
  for (double v : z) sum += v * v;
  out.nees = sum / static_cast<double>(z.size());
  std::tie(out.low, out.high) = ChiSquareBandPerDof(static_cast<int>(z.size()));
  out.worst_z = *std::max_element(z.begin(), z.end());
  return out;
}

// Prints every direction and expects: the NEES of the observable and of the kept reports,
// each over 3 drives or more, inside its band (for the directions in `upper_bound_only`, below
// its upper end only); and the largest z of all held directions below the two-sided 95 % bound
// for that many draws (Bonferroni), since a held direction's error is the nominal value's,
// drawn with the prior sigma it is reported with.
inline void ExpectConsistent(const ConsistencyComponents& components,
                             const std::set<std::string>& upper_bound_only = {}) {
  ASSERT_FALSE(components.empty()) << "no direction was calibrated";
  for (const std::string& name : upper_bound_only) {
    const auto it = components.find(name);
    EXPECT_TRUE(it != components.end() &&
                it->second.observable_z.size() + it->second.kept_z.size() >= 3)
        << name << ": held to the upper end only, yet not estimated on 3 drives or more";
  }
  size_t held = 0;
  for (const auto& [name, c] : components) held += c.held_z.size();
  const double held_bound = TwoSidedNormalQuantile(0.05 / std::max<size_t>(held, 1));
  std::cout << std::fixed << std::setprecision(2) << "per component, z = |e| / sigma:\n";
  for (const auto& [name, c] : components) {
    const Nees kinds[] = {NeesOf("observable", c.observable_z), NeesOf("kept", c.kept_z)};
    std::cout << "  " << name;
    for (const Nees& n : kinds) {
      if (n.drives == 0) continue;
      std::cout << "; " << n.kind << " NEES " << n.nees << " (" << n.drives << ") [" << n.low
                << ", " << n.high << "], worst " << n.worst_z;
    }
    if (!c.held_z.empty()) {
      std::cout << "; held " << c.held_z.size() << ", worst " << c.worst_held_z << " (seed "
                << c.worst_held_seed << ")";
    }
    std::cout << std::endl;
    for (const Nees& n : kinds) {
      if (n.drives < 3) continue;  // fewer make no statement about the average
      EXPECT_LT(n.nees, n.high) << name << " (" << n.kind
                                << "): the reported sigmas are too small (overconfident)";
      if (upper_bound_only.count(name) != 0) continue;
      EXPECT_GT(n.nees, n.low) << name << " (" << n.kind
                               << "): the reported sigmas are too large (pessimistic)";
    }
    EXPECT_LE(c.worst_held_z, held_bound)
        << name << " (seed " << c.worst_held_seed
        << "): a held direction's nominal value is farther from the truth than its sigma allows";
  }
  std::cout << held << " held directions, bound " << held_bound << "\n";
}

}  // namespace test
}  // namespace autocal
