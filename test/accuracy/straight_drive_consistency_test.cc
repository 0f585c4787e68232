// Is the reported uncertainty true where the drive is weak? On a straight drive the vehicle
// frame's pitch (q_I_V), the IMU's tilt and the accelerometer bias trade against each other:
// only the speed changes separate them. The offline calibration without the LiDAR
// (problems/imu_wheel_gnss.yaml) of simulated straight drives (the CAN-bus car: a 104 Hz
// phone-grade IMU mounted z-down, wheels at 83 Hz, GNSS at 10 Hz; 60 s, one heading, speed
// changes and a stop), each with accelerometer turn-on biases of 0.05 or 0.1 m/s^2 per axis
// (1-sigma), is compared with its truth. Per component, z^2 = e^2 / sigma^2 averaged over the
// drives (NEES) must lie in the two-sided 95 % band of chi^2(n) / n for its n drives, separately
// for the drives that report it observable and those that keep it (their estimate with its
// posterior sigma, not reported observable). A held direction (set to its nominal value and
// reported with its prior sigma) must hold the truth within the two-sided 95 % bound for all
// held directions together (Bonferroni). The mount's roll and pitch priors carry gravity's up
// axis (docs/calibration.md, Eq. C4). The sensor clocks are exact here (the wheel bursts
// and the receiver's late stamps are another subject). About 30 s on one core.
// Figures: docs/calibration.md, "Straight drives".
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sim/simulator.h"
#include "support/test_paths.h"

namespace autocal {
namespace {

constexpr int kSeeds = 20;

// How a drive reported a direction: observable (posterior sigma within its limit), kept (its
// estimate with its posterior sigma, not reported observable) or held (set to the nominal
// value and reported with the prior sigma).
enum class Report { kObservable, kKept, kHeld };

// Per component, over the drives: z = |e| / sigma of each report kind.
struct Component {
  std::vector<double> observable_z, kept_z, held_z;
  double worst_held_z = 0.0;
  int worst_held_seed = 0;
};
using Components = std::map<std::string, Component>;

// `error` = estimate - truth and `from_nominal` = estimate - the prior's centre (where a held
// direction is held) in the direction.
void Add(const std::string& name, double error, double from_nominal,
         const std::optional<double>& sigma, bool observable, int seed, Components* components) {
  if (!sigma || !(*sigma > 0.0)) return;
  Component& c = (*components)[name];
  const double z = std::abs(error) / *sigma;
  // Held directions sit at the nominal value to within the held prior's 1e-6 of its sigma.
  const Report report = observable                                ? Report::kObservable
                        : std::abs(from_nominal) <= 1e-3 * *sigma ? Report::kHeld
                                                                  : Report::kKept;
  switch (report) {
    case Report::kObservable:
      c.observable_z.push_back(z);
      break;
    case Report::kKept:
      c.kept_z.push_back(z);
      break;
    case Report::kHeld:
      c.held_z.push_back(z);
      if (z > c.worst_held_z) {
        c.worst_held_z = z;
        c.worst_held_seed = seed;
      }
      break;
  }
}

bool Flag(const std::vector<bool>& flags, size_t index) {
  if (flags.empty()) return true;
  return flags.size() == 1 ? flags[0] : flags[index];
}

// The two-sided standard normal quantile: z with P(|N(0,1)| > z) = p (bisection).
double TwoSidedNormalQuantile(double p) {
  double low = 0.0, high = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (low + high);
    (std::erfc(mid / std::sqrt(2.0)) > p ? low : high) = mid;
  }
  return 0.5 * (low + high);
}

// Two-sided 95 % band of chi^2(n) / n by the Wilson-Hilferty approximation (within a few
// percent of the exact quantiles for n >= 3, a fraction of a percent for n >= 10).
std::pair<double, double> ChiSquareBandPerDof(int n) {
  const double z = 1.959964;
  const double c = 2.0 / (9.0 * n);
  const auto bound = [&](double zz) { return std::pow(1.0 - c + zz * std::sqrt(c), 3); };
  return {bound(-z), bound(z)};
}

// The straight drive of seed `seed` and its dataset, in memory.
struct Drive {
  sim::Simulator simulator;
  io::Dataset dataset;
};

sim::SimulationOptions StraightDriveOptions(int seed) {
  sim::SimulationOptions options = sim::CanBusCarOptions();
  options.seed = static_cast<uint64_t>(seed);
  options.imu.initial_accel_bias_sigma_m_s2 = seed % 2 == 0 ? 0.1 : 0.05;
  options.wheel.burst_size = 1;
  options.gnss.time_offset_gnss_imu_s = 0.0;
  return options;
}

Drive SimulateDrive(int seed) {
  Drive drive{sim::Simulator(StraightDriveOptions(seed)), {}};
  const sim::SimulatedLog log = sim::Simulate(drive.simulator);
  drive.dataset.directory = "straight drive, seed " + std::to_string(seed);
  drive.dataset.sensors = drive.simulator.sensors_config();
  drive.dataset.imu = log.imu.samples;
  drive.dataset.wheel = log.wheel;
  drive.dataset.gnss = log.gnss.fixes;
  return drive;
}

// Every calibrated component of one drive against its truth.
void AddDrive(const pipeline::OfflineCalibrationResult& result, const sensors::Calibration& truth,
              int seed, Components* components) {
  const sensors::Calibration& estimate = result.calibration.value;
  const sensors::Calibration& nominal = result.prior_centre;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  const char* axes[] = {"x", "y", "z"};
  // q_I_V's sigmas are of the right perturbation q_truth = q_estimate Exp(delta), delta in V:
  // roll, pitch and yaw of the mount.
  const Eigen::Vector3d error_deg =
      -geometry::Log(estimate.q_I_V.conjugate() * truth.q_I_V) * kRadToDeg;
  const Eigen::Vector3d from_nominal_deg =
      geometry::Log(nominal.q_I_V.conjugate() * estimate.q_I_V) * kRadToDeg;
  const char* angles[] = {"roll", "pitch", "yaw"};
  for (size_t a = 0; a < 3; ++a) {
    if (u.T_I_V.sigma_rot_deg) {
      Add(std::string("q_I_V ") + angles[a], error_deg(a), from_nominal_deg(a),
          (*u.T_I_V.sigma_rot_deg)(a), Flag(u.T_I_V.observable, a), seed, components);
    }
    if (u.T_I_V.sigma_p_m) {
      Add(std::string("p_I_V ") + axes[a], estimate.p_I_V(a) - truth.p_I_V(a),
          estimate.p_I_V(a) - nominal.p_I_V(a), (*u.T_I_V.sigma_p_m)(a),
          Flag(u.T_I_V.observable, 3 + a), seed, components);
    }
    if (u.p_I_A_m.sigma) {
      Add(std::string("lever arm ") + axes[a], estimate.p_I_A(a) - truth.p_I_A(a),
          estimate.p_I_A(a) - nominal.p_I_A(a), (*u.p_I_A_m.sigma)(a),
          Flag(u.p_I_A_m.observable, a), seed, components);
    }
  }
  Add("wheel radius left", estimate.wheel_radius_left_m - truth.wheel_radius_left_m,
      estimate.wheel_radius_left_m - nominal.wheel_radius_left_m, u.wheel_radius_left_m.sigma,
      u.wheel_radius_left_m.observable.value_or(true), seed, components);
  Add("wheel radius right", estimate.wheel_radius_right_m - truth.wheel_radius_right_m,
      estimate.wheel_radius_right_m - nominal.wheel_radius_right_m, u.wheel_radius_right_m.sigma,
      u.wheel_radius_right_m.observable.value_or(true), seed, components);
  Add("track width", estimate.track_width_m - truth.track_width_m,
      estimate.track_width_m - nominal.track_width_m, u.track_width_m.sigma,
      u.track_width_m.observable.value_or(true), seed, components);
}

// The NEES of one report kind of one component and its 95 % band.
struct Nees {
  std::string kind;
  size_t drives = 0;
  double nees = 0.0, low = 0.0, high = 0.0, worst_z = 0.0;
};

Nees NeesOf(const std::string& kind, const std::vector<double>& z) {
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

TEST(StraightDriveConsistency, NormalizedErrorsPerComponentMatchTheReportedSigmas) {
  const io::Problem problem = io::ReadProblemYaml(
      (std::filesystem::path(AUTOCAL_SOURCE_DIR) / "problems" / "imu_wheel_gnss.yaml").string());
  Components components;
  int calibrated = 0;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    const Drive drive = SimulateDrive(seed);
    pipeline::OfflineCalibrationResult result;
    try {
      result = pipeline::CalibrateDataset(drive.dataset, problem);
    } catch (const Error& e) {
      // A drive that cannot be calibrated says so; it carries no sample.
      std::cout << "seed " << seed << ": not calibrated: " << e.what() << "\n";
      continue;
    }
    ++calibrated;
    const sensors::Calibration& truth = drive.simulator.true_calibration();
    const Eigen::Vector3d error_deg =
        -geometry::Log(result.calibration.value.q_I_V.conjugate() * truth.q_I_V) * kRadToDeg;
    std::cout << std::setprecision(3) << "seed " << seed << ": q_I_V error (roll, pitch, yaw) "
              << error_deg.transpose() << " deg, sigma "
              << result.calibration.uncertainty.T_I_V.sigma_rot_deg
                     .value_or(Eigen::Vector3d::Constant(NAN))
                     .transpose()
              << " deg" << std::endl;
    AddDrive(result, truth, seed, &components);
  }
  ASSERT_GE(calibrated, kSeeds * 3 / 4) << "too few drives calibrated for a consistency statement";

  // A held direction's error is the nominal value's, drawn with the prior sigma it is reported
  // with: the largest of all held directions stays below the two-sided 95 % bound for that
  // many draws (Bonferroni).
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
    // 3 drives or more make a statement about the average.
    for (const Nees& n : kinds) {
      if (n.drives < 3) continue;
      EXPECT_LT(n.nees, n.high) << name << " (" << n.kind
                                << "): the reported sigmas are too small (overconfident)";
      EXPECT_GT(n.nees, n.low) << name << " (" << n.kind
                               << "): the reported sigmas are too large (pessimistic)";
    }
    EXPECT_LE(c.worst_held_z, held_bound)
        << name << " (seed " << c.worst_held_seed
        << "): a held direction's nominal value is farther from the truth than its sigma allows";
  }
  std::cout << held << " held directions, bound " << held_bound << "\n";
}

}  // namespace
}  // namespace autocal
