#include "calibration_steps.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/time.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/factors/gnss_factor.h"
#include "autocal/factors/imu_factor.h"
#include "autocal/factors/wheel_factor.h"
#include "problem_blocks.h"

namespace autocal {
namespace pipeline {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void Report(const OfflineCalibrationOptions& options, const std::string& stage, double fraction,
            double cost, double seconds_left) {
  if (!options.progress) return;
  CalibrationProgress progress;
  progress.stage = stage;
  progress.fraction = fraction;
  progress.cost = cost;
  progress.seconds_left = seconds_left;
  options.progress(progress);
}

bool Estimated(io::BlockMode mode) { return mode != io::BlockMode::kFixed; }

sensors::Calibration StartFromInitializer(const sensors::Calibration& nominal,
                                          const io::ProblemCalibration& blocks,
                                          const estimation::CalibrationInitialization& init) {
  sensors::Calibration calibration = nominal;
  if (Estimated(blocks.T_I_L.rotation.mode)) calibration.q_I_L = init.q_I_L;
  if (Estimated(blocks.T_I_L.translation.mode)) calibration.p_I_L = init.p_I_L;
  if (Estimated(blocks.time_offset_lidar_imu_s.mode)) {
    calibration.time_offset_lidar_imu_s = init.time_offset_lidar_imu_s;
  }
  return calibration;
}

std::string Join(const std::vector<std::string>& parts, const std::string& separator) {
  std::string out;
  for (size_t i = 0; i < parts.size(); ++i) out += (i == 0 ? "" : separator) + parts[i];
  return out;
}

namespace {

// The median interval between consecutive stamps in seconds (0 for fewer than two).
template <typename Samples>
double MedianIntervalS(const Samples& samples) {
  if (samples.size() < 2) return 0.0;
  std::vector<int64_t> intervals_ns;
  intervals_ns.reserve(samples.size() - 1);
  for (size_t i = 1; i < samples.size(); ++i) {
    intervals_ns.push_back(samples[i].t_ns - samples[i - 1].t_ns);
  }
  const auto middle = intervals_ns.begin() + static_cast<std::ptrdiff_t>(intervals_ns.size() / 2);
  std::nth_element(intervals_ns.begin(), middle, intervals_ns.end());
  return NsToSeconds(*middle);
}

// How many of `samples` lie within the keyframes' time span.
template <typename Samples>
size_t CountWithin(const Samples& samples, const std::vector<estimation::Keyframe>& keyframes) {
  size_t n = 0;
  for (const auto& sample : samples) {
    n += sample.t_ns >= keyframes.front().t_ns && sample.t_ns <= keyframes.back().t_ns;
  }
  return n;
}

// Why a sensor with samples gave no factor: none inside the keyframes' span, or none close
// enough on both sides of any keyframe. `file` names the samples ("wheel.csv").
template <typename Samples>
std::string NoFactorReason(const Samples& samples, const std::vector<estimation::Keyframe>& kfs,
                           const std::string& file, const std::string& gap_name, double max_gap_s) {
  const size_t inside = kfs.empty() ? 0 : CountWithin(samples, kfs);
  if (inside == 0) {
    return file + ": 0 of " + std::to_string(samples.size()) +
           " samples fall inside the keyframes' time span";
  }
  return file + ": no keyframe has samples within " + gap_name + "=" + FormatFixed(max_gap_s, 4) +
         " s on both sides (the median interval of " + file + " is " +
         FormatFixed(MedianIntervalS(samples), 4) + " s)";
}

[[noreturn]] void ThrowNoFactor(const io::Dataset& dataset, const std::string& sensor,
                                const std::string& reason) {
  throw Error("dataset " + dataset.directory + ": no " + sensor + " factor in the solve (" +
              reason + "); nothing is written");
}

}  // namespace

void SensorFactors::Add(ceres::Problem* p, std::vector<estimation::Keyframe>* keyframes,
                        sensors::Calibration* c) const {
  const io::ProblemCalibration& b = problem->calibration;
  if (use_wheel) {
    p->AddParameterBlock(c->q_I_V.coeffs().data(), 4, quaternion_manifold);
    estimation::KeyframeWheelOptions wheel;
    // A sensors.yaml without a wheel: section (or no sensors.yaml) means the encoder defaults
    // of sensors/sensor_config.h (datasets/README.md).
    wheel.factor = factors::WheelFactorOptions::FromEncoderNoise(
        dataset->sensors.wheel.value_or(sensors::WheelConfig()), nominal->wheel_radius_left_m,
        nominal->track_width_m);
    wheel.factor.shared_radius = b.wheel_radius_shared;
    wheel.loss = problem->loss.wheel;
    wheel.estimate_vehicle_rotation = Estimated(b.T_I_V.rotation.mode);
    wheel.estimate_vehicle_translation = Estimated(b.T_I_V.translation.mode);
    wheel.estimate_radii = Estimated(b.wheel_radius_left_m.mode);
    wheel.estimate_track_width = Estimated(b.track_width_m.mode);
    if (estimation::AddWheelFactors(p, dataset->imu, dataset->wheel, keyframes, c, wheel) == 0) {
      std::string reason = NoFactorReason(dataset->wheel, *keyframes, "wheel.csv",
                                          "max_wheel_gap_s", wheel.max_wheel_gap_s);
      if (reason.find("no keyframe") != std::string::npos) {
        reason += " or IMU samples within max_imu_gap_s=" + FormatFixed(wheel.max_imu_gap_s, 4) +
                  " s (imu.csv: " + FormatFixed(MedianIntervalS(dataset->imu), 4) + " s)";
      }
      ThrowNoFactor(*dataset, "wheel", reason);
    }
  }
  if (use_gnss) {
    estimation::KeyframeGnssOptions gnss;
    gnss.loss = problem->loss.gnss;
    gnss.estimate_lever_arm = Estimated(b.p_I_A_m.mode);
    if (estimation::AddGnssFactors(p, dataset->gnss, *enu, keyframes, c, gnss) == 0) {
      ThrowNoFactor(*dataset, "GNSS",
                    NoFactorReason(dataset->gnss, *keyframes, "gnss.csv", "max_fix_gap_s",
                                   gnss.max_fix_gap_s));
    }
  }
  estimation::AddBlockPriors(*blocks, problem->loss.prior, p);
}

void RequireSamplesAfter(const io::Dataset& dataset, bool use_wheel, bool use_gnss, int64_t t0_ns) {
  const auto require = [&](bool used, const auto& samples, const char* file) {
    if (!used) return;
    for (const auto& sample : samples) {
      if (sample.t_ns > t0_ns) return;
    }
    throw Error(
        "dataset " + dataset.directory + ": " + file + ": 0 of " + std::to_string(samples.size()) +
        " samples after the online estimator's initial state at " + std::to_string(t0_ns) +
        " ns (the log's last is at " + std::to_string(samples.empty() ? 0 : samples.back().t_ns) +
        " ns); nothing was estimated");
  };
  require(use_wheel, dataset.wheel, "wheel.csv");
  require(use_gnss, dataset.gnss, "gnss.csv");
}

void RequireStreamedSamples(const io::Dataset& dataset, bool use_wheel, bool use_gnss,
                            const estimation::SlidingWindowCounters& counters) {
  const auto require = [&](bool used, int64_t accepted, size_t total, const char* sensor,
                           const char* file) {
    if (!used || accepted > 0) return;
    throw Error("dataset " + dataset.directory + ": no " + sensor +
                " sample reached the sliding window (" + file + ": 0 of " + std::to_string(total) +
                " samples after the initial state, in order and not late); nothing was "
                "estimated");
  };
  require(use_wheel, counters.wheel_accepted, dataset.wheel.size(), "wheel", "wheel.csv");
  require(use_gnss, counters.gnss_accepted, dataset.gnss.size(), "GNSS", "gnss.csv");
}

std::map<std::string, std::vector<double>> WhitenedResidualsBySensor(ceres::Problem* problem) {
  std::vector<ceres::ResidualBlockId> all;
  problem->GetResidualBlocks(&all);
  std::map<std::string, std::vector<ceres::ResidualBlockId>> ids;
  for (ceres::ResidualBlockId id : all) {
    const ceres::CostFunction* f = problem->GetCostFunctionForResidualBlock(id);
    if (dynamic_cast<const factors::ImuFactor*>(f)) ids["imu"].push_back(id);
    if (dynamic_cast<const factors::WheelFactor*>(f)) ids["wheel"].push_back(id);
    if (dynamic_cast<const factors::GnssFactor*>(f)) ids["gnss"].push_back(id);
  }
  std::map<std::string, std::vector<double>> out;
  for (const auto& [sensor, blocks] : ids) {
    ceres::Problem::EvaluateOptions evaluate;
    evaluate.residual_blocks = blocks;
    evaluate.apply_loss_function = false;
    problem->Evaluate(evaluate, nullptr, &out[sensor], nullptr, nullptr);
  }
  return out;
}

void Conclude(const io::Dataset& dataset, const io::Problem& problem,
              const OfflineCalibrationOptions& options,
              const std::vector<estimation::EstimatedBlock>& blocks_estimated,
              const estimation::BlockCovariance& covariance,
              const std::vector<estimation::Keyframe>& keyframes, sensors::Calibration* calibration,
              std::chrono::steady_clock::time_point start, OfflineCalibrationResult* result) {
  if (problem.sensors.lidar && result->batch.associated_points == 0) {
    ThrowNoFactor(dataset, "LiDAR",
                  "lidar.csv: no point of the " + std::to_string(keyframes.size()) +
                      " keyframe sweeps was associated with a plane");
  }
  io::CalibrationFile& file = result->calibration;
  const std::vector<std::string> implausible = estimation::ImplausibleDirections(
      blocks_estimated, covariance, options.max_prior_deviation_sigmas);
  if (!implausible.empty()) {
    throw Error("dataset " + dataset.directory +
                ": the calibration solve did not converge to a plausible result (" +
                Join(implausible, "; ") +
                "); nothing is written. The drive may not excite these blocks: fix them or "
                "give them priors in the problem file");
  }
  if (covariance.ok) {
    const estimation::BlockObservability observability =
        estimation::HoldUnobservableDirections(blocks_estimated, covariance);
    FillUncertainty(blocks_estimated, observability, &file.uncertainty);
    result->warnings.insert(result->warnings.end(), observability.warnings.begin(),
                            observability.warnings.end());
  } else {
    result->warnings.push_back(
        "the covariance of the calibration could not be computed; no sigma and no "
        "observability are reported");
  }
  if (problem.calibration.wheel_radius_shared) {
    calibration->wheel_radius_right_m = calibration->wheel_radius_left_m;
  }
  if (problem.sensors.wheel && dataset.wheel.empty()) {
    result->warnings.push_back(
        "the dataset has no wheel samples: wheel blocks keep their nominal value");
  }
  file.value = *calibration;
  file.solver["keyframes"] = std::to_string(keyframes.size());
  for (const estimation::Keyframe& kf : keyframes) {
    io::TrajectorySample sample;
    sample.t_ns = kf.t_ns;
    sample.T_W_I = geometry::Pose3d(kf.q_W_I.normalized(), kf.p_W_I);
    sample.v_W_I = kf.v_W_I;
    result->trajectory.push_back(sample);
  }
  for (const auto& [sensor, residuals] : result->whitened_residuals) {
    double sum = 0.0;
    for (double r : residuals.after) sum += r * r;
    if (!residuals.after.empty()) {
      file.residuals[sensor]["whitened_rms"] =
          std::sqrt(sum / static_cast<double>(residuals.after.size()));
      file.residuals[sensor]["rows"] = static_cast<double>(residuals.after.size());
    }
  }
  result->seconds_total = SecondsSince(start);
  result->seconds_solve =
      result->seconds_total - result->seconds_loading - result->seconds_initialization;
  file.solver["seconds"] = std::to_string(result->seconds_total);
  file.solver["seconds_loading"] = std::to_string(result->seconds_loading);
  file.solver["seconds_initialization"] = std::to_string(result->seconds_initialization);
  file.solver["seconds_solve"] = std::to_string(result->seconds_solve);
}

}  // namespace pipeline
}  // namespace autocal
