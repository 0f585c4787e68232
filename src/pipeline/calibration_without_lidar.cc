#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/estimation/dead_reckoning_keyframes.h"
#include "autocal/estimation/gnss_inertial_keyframes.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/geometry/manifolds.h"
#include "calibration_steps.h"
#include "clock_initialization.h"
#include "problem_blocks.h"
#include "residual_groups.h"

namespace autocal {
namespace pipeline {

namespace {

// Keyframes every keyframe period (the caller's inertial_keyframe_period_s, else the timing's)
// over [first_ns, last_ns], the span the IMU shares with `other` (named in the error), none in
// an IMU dropout (KeyframesEvery, which warns of them).
std::vector<estimation::Keyframe> KeyframeGrid(const io::Dataset& dataset,
                                               const OfflineCalibrationOptions& options,
                                               const TimingLimits& timing, int64_t first_ns,
                                               int64_t last_ns, const std::string& other,
                                               std::vector<std::string>* warnings) {
  const int64_t period_ns =
      SecondsToNs(options.inertial_keyframe_period_s.value_or(timing.keyframe_period_s));
  if (!(period_ns > 0)) throw Error("inertial_keyframe_period_s must be positive");
  std::vector<estimation::Keyframe> keyframes =
      KeyframesEvery(dataset.imu, first_ns, last_ns, period_ns, warnings);
  if (keyframes.size() < 2) {
    throw Error("dataset " + dataset.directory + ": the IMU and " + other +
                " overlap too briefly for two keyframes");
  }
  return keyframes;
}

// Keyframes over the span the IMU and the fixes share, placed on the GNSS track and refined
// with the IMU and the wheels.
std::vector<estimation::Keyframe> KeyframesOnGnssTrack(
    const io::Dataset& dataset, const io::Problem& problem,
    const OfflineCalibrationOptions& options, const TimingLimits& timing,
    const sensors::EnuConverter& enu, bool use_wheel, const sensors::Calibration& calibration,
    estimation::GnssInertialKeyframes* placed, std::vector<std::string>* warnings) {
  std::vector<estimation::Keyframe> keyframes = KeyframeGrid(
      dataset, options, timing, std::max(dataset.imu.front().t_ns, dataset.gnss.front().t_ns),
      std::min(dataset.imu.back().t_ns, dataset.gnss.back().t_ns), "the GNSS fixes", warnings);
  *placed = estimation::KeyframesFromGnssAndImu(
      &keyframes, dataset.imu, StartWheelData(dataset, use_wheel), dataset.gnss, enu, calibration,
      GnssInertialStart(dataset, problem, timing));
  return keyframes;
}

// Keyframes over the span the IMU and the wheels share (the wheels on the IMU clock), placed
// by dead reckoning: a log without a position reference.
std::vector<estimation::Keyframe> KeyframesByDeadReckoning(const io::Dataset& dataset,
                                                           const OfflineCalibrationOptions& options,
                                                           const TimingLimits& timing,
                                                           const sensors::Calibration& calibration,
                                                           std::vector<std::string>* warnings) {
  estimation::ScalarSeries speed, yaw_rate;
  WheelSpeedAndYawRate(dataset, calibration, &speed, &yaw_rate);
  speed = estimation::Shifted(speed, calibration.time_offset_wheel_imu_s);
  if (speed.size() < 2) {
    throw Error("dataset " + dataset.directory + ": fewer than two wheel samples");
  }
  std::vector<estimation::Keyframe> keyframes =
      KeyframeGrid(dataset, options, timing, std::max(dataset.imu.front().t_ns, speed.front().t_ns),
                   std::min(dataset.imu.back().t_ns, speed.back().t_ns), "the wheels", warnings);
  estimation::PlaceKeyframesByDeadReckoning(&keyframes, dataset.imu, speed, calibration.q_I_V,
                                            calibration.p_I_V);
  return keyframes;
}

// At most this many solves, each on factors paired at the clocks the one before ended at
// (Eq. K17); measured: a start 20 ms off needs three.
constexpr int kMaxClockPairingSolves = 5;

// The gauge of a log without a position reference: the first keyframe's position and yaw.
constexpr double kGaugePositionSigmaM = 1e-3;
constexpr double kGaugeYawSigmaRad = 1e-4;

// The joint solve's summary, or an autocal::Error when it is unusable. Ceres' time is added
// to *seconds_ceres.
ceres::Solver::Summary Solve(const io::Dataset& dataset, const io::Problem& problem,
                             ceres::Problem* p, double* seconds_ceres) {
  ceres::Solver::Summary summary;
  ceres::Solve(
      JointSolverOptions(problem, problem.solver.max_iterations * problem.solver.outer_iterations),
      p, &summary);
  *seconds_ceres += summary.total_time_in_seconds;
  if (!summary.IsSolutionUsable()) {
    throw Error("dataset " + dataset.directory +
                ": the calibration solve failed: " + summary.message);
  }
  return summary;
}

// The joint problem's factors on `keyframes` and `calibration`: IMU factors, the first
// keyframe's bias priors (the GNSS-inertial start's), the dead-reckoning gauge without GNSS,
// and the sensors' factors with the blocks' priors.
void AddJointFactors(const io::Dataset& dataset, const SensorFactors& sensor_factors,
                     std::vector<estimation::Keyframe>* keyframes,
                     sensors::Calibration* calibration, ceres::Problem* p) {
  for (estimation::Keyframe& kf : *keyframes) {
    p->AddParameterBlock(kf.q_W_I.coeffs().data(), 4, sensor_factors.quaternion_manifold);
  }
  estimation::KeyframeImuOptions imu;
  imu.noise = dataset.sensors.imu.noise;
  imu.gravity_m_s2 = dataset.sensors.imu.gravity_m_s2;
  imu.num_threads = sensor_factors.problem->solver.num_threads;
  estimation::AddImuFactors(p, dataset.imu, keyframes, imu);
  const estimation::GnssInertialKeyframesOptions bias_priors;
  estimation::AddBiasPriors(p, &keyframes->front(), bias_priors.gyro_bias_prior_sigma_rad_s,
                            bias_priors.accel_bias_prior_sigma_m_s2);
  if (!sensor_factors.use_gnss) {
    estimation::AddDeadReckoningGauge(p, &keyframes->front(), kGaugePositionSigmaM,
                                      kGaugeYawSigmaRad);
  }
  sensor_factors.Add(p, keyframes, calibration);
}

// A new joint problem with AddJointFactors' factors.
std::unique_ptr<ceres::Problem> NewJointProblem(const io::Dataset& dataset,
                                                const SensorFactors& sensor_factors,
                                                std::vector<estimation::Keyframe>* keyframes,
                                                sensors::Calibration* calibration) {
  ceres::Problem::Options options;
  options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  auto p = std::make_unique<ceres::Problem>(options);
  AddJointFactors(dataset, sensor_factors, keyframes, calibration, p.get());
  return p;
}

// The solve of *joint, built at `calibration`'s clocks. Each keyframe takes the wheel sample
// and the fix nearest it on the clocks' estimates (Eq. K17): while a solve moves a clock onto
// other samples, the factors are added again at the clocks it ended at and solved again, at
// most kMaxClockPairingSolves times in all (a warning says when the pairing still moved then).
// *solves counts the solves; result->batch.seconds_solver sums Ceres' time.
ceres::Solver::Summary SolvePairedAtTheClocks(const io::Dataset& dataset,
                                              const SensorFactors& sensor_factors,
                                              std::vector<estimation::Keyframe>* keyframes,
                                              sensors::Calibration* calibration,
                                              std::unique_ptr<ceres::Problem>* joint, int* solves,
                                              OfflineCalibrationResult* result) {
  const io::Problem& problem = *sensor_factors.problem;
  double* seconds_ceres = &result->batch.seconds_solver;
  sensors::Calibration paired = *calibration;  // the clocks the factors were paired at
  ceres::Solver::Summary summary = Solve(dataset, problem, joint->get(), seconds_ceres);
  for (*solves = 1; sensor_factors.PairingChanges(*keyframes, paired, *calibration); ++*solves) {
    if (*solves == kMaxClockPairingSolves) {
      result->warnings.push_back(
          "the wheel or GNSS clock still moved the keyframes onto other " +
          std::string("samples after ") + std::to_string(*solves) +
          " solves: the last factors are paired at the clocks before the last "
          "solve");
      break;
    }
    paired = *calibration;
    *joint = NewJointProblem(dataset, sensor_factors, keyframes, calibration);
    summary = Solve(dataset, problem, joint->get(), seconds_ceres);
  }
  return summary;
}

// SolvePairedAtTheClocks, and again with the GNSS rows' sigma scaled where the fixes scatter
// beyond their stated std about the solved trajectory (MeasureGnssNoise, Eq. N2).
ceres::Solver::Summary SolveWithGnssNoiseFromResiduals(
    const io::Dataset& dataset, SensorFactors* sensor_factors,
    std::vector<estimation::Keyframe>* keyframes, sensors::Calibration* calibration,
    std::unique_ptr<ceres::Problem>* joint, int* solves, OfflineCalibrationResult* result) {
  ceres::Solver::Summary summary = SolvePairedAtTheClocks(dataset, *sensor_factors, keyframes,
                                                          calibration, joint, solves, result);
  if (!sensor_factors->use_gnss) return summary;
  const estimation::GnssNoiseFromResiduals noise =
      MeasureGnssNoise(*sensor_factors, keyframes, calibration);
  RecordGnssNoiseScale(noise.Scale(), &result->calibration);
  if (noise.Scale().IsOne()) return summary;
  result->warnings.push_back(GnssNoiseWarning(noise));
  sensor_factors->gnss_noise_scale = noise.Scale();
  WhitenGnssRowsBeforeAlike(noise.Scale(), &result->whitened_residuals);
  *joint = NewJointProblem(dataset, *sensor_factors, keyframes, calibration);
  int scaled_solves = 0;
  summary = SolvePairedAtTheClocks(dataset, *sensor_factors, keyframes, calibration, joint,
                                   &scaled_solves, result);
  *solves += scaled_solves;
  return summary;
}

}  // namespace

OfflineCalibrationResult CalibrateWithoutLidar(const io::Dataset& dataset,
                                               const io::Problem& problem,
                                               const OfflineCalibrationOptions& options,
                                               std::chrono::steady_clock::time_point start) {
  const bool use_gnss = problem.sensors.gnss && !dataset.gnss.empty();
  const bool use_wheel = problem.sensors.wheel && dataset.wheel_sample_count() > 0;
  if (!use_gnss && !use_wheel) {
    throw Error("problem " + problem.path +
                ": a calibration without the LiDAR needs GNSS (sensors.gnss and gnss.csv: the "
                "keyframes are placed on its track) or the wheels (sensors.wheel and their "
                "file: the keyframes are placed by dead reckoning)");
  }
  OfflineCalibrationResult result;
  // Loading: what CalibrateDataset did before (the checks, the IMU noise from the data), as
  // with the LiDAR; the log's files are read by the caller.
  result.seconds_loading = SecondsSince(start);
  result.nominal = dataset.sensors.nominal_calibration;
  std::optional<sensors::EnuConverter> enu;
  if (use_gnss) enu.emplace(sensors::EnuConverter::AtFirstFix(dataset.gnss));
  const TimingLimits timing = DeriveTimingLimits(dataset, problem, use_wheel, use_gnss);
  if (use_gnss) {
    for (const sensors::GnssFix& fix : dataset.gnss) {
      result.gnss_positions_W.push_back(enu->ToEnu(fix));
    }
  } else {
    result.warnings.push_back(
        "no position reference (no GNSS, no LiDAR): the trajectory starts at the origin with yaw "
        "zero and is dead reckoned from the IMU and the wheels");
  }

  // 1. Keyframes over the span the IMU shares with the fixes, or without them with the wheels.
  Report(options, "initializing", 0.0, 0.0, 0.0);
  sensors::Calibration calibration = result.nominal;
  io::SensorsConfig priors = dataset.sensors;  // the prior centres: the nominal calibration
  const ClockInitialization initialization = InitializeMountAndClocks(
      dataset, problem, MaxNominalMountDeg(problem, dataset.sensors, options), &calibration,
      &priors.nominal_calibration, &result.warnings);
  result.wheel_clock_initialization = initialization.wheel;
  result.gnss_clock_initialization = initialization.gnss;
  estimation::GnssInertialKeyframes placed;
  std::vector<estimation::Keyframe> keyframes =
      use_gnss ? KeyframesOnGnssTrack(dataset, problem, options, timing, *enu, use_wheel,
                                      calibration, &placed, &result.warnings)
               : KeyframesByDeadReckoning(dataset, options, timing, calibration, &result.warnings);
  result.seconds_initialization = SecondsSince(start) - result.seconds_loading;
  Report(options, "initializing", 1.0, 0.0, 0.0);

  // 2. The joint solve: IMU, wheel and GNSS factors and the blocks' priors. The first keyframe's
  //    bias priors are the GNSS-inertial start's.
  const estimation::GnssInertialKeyframesOptions bias_priors;
  std::vector<estimation::EstimatedBlock> blocks_estimated =
      EstimatedBlocks(problem, priors, options, use_wheel, use_gnss, &calibration);
  FuseUpAxisIntoMountPrior(initialization, problem, bias_priors.accel_bias_prior_sigma_m_s2,
                           dataset.sensors.imu.noise.accelerometer_random_walk,
                           dataset.sensors.imu.gravity_m_s2, &blocks_estimated,
                           &priors.nominal_calibration);
  result.prior_centre = priors.nominal_calibration;
  geometry::RightQuaternionManifold quaternion_manifold;
  SensorFactors sensor_factors{&dataset,
                               &problem,
                               &result.nominal,
                               use_wheel,
                               use_gnss,
                               enu ? &*enu : nullptr,
                               &blocks_estimated,
                               &quaternion_manifold,
                               &timing};
  if (use_wheel) {
    sensor_factors.wheel_noise_scale =
        WheelNoiseScale(dataset, calibration, result.nominal, &result.warnings);
  }
  estimation::PlanarRotationRows planar_rotation;
  sensor_factors.planar_rotation = &planar_rotation;
  std::unique_ptr<ceres::Problem> joint =
      NewJointProblem(dataset, sensor_factors, &keyframes, &calibration);
  RecordPlanarRotation(planar_rotation, &result.calibration);
  for (auto& [sensor, rows] : WhitenedResidualsBySensor(joint.get())) {
    result.whitened_residuals[sensor].before = std::move(rows);
  }
  Report(options, "solving", 0.0, 0.0, 0.0);
  int solves = 0;
  const ceres::Solver::Summary summary = SolveWithGnssNoiseFromResiduals(
      dataset, &sensor_factors, &keyframes, &calibration, &joint, &solves, &result);
  Report(options, "solving", 1.0, summary.final_cost, 0.0);
  if (summary.termination_type == ceres::NO_CONVERGENCE) {
    // The values and their sigma are those of a point short of the minimum, as with the
    // LiDAR when its outer loop stops still moving (StillMovingWarning).
    result.warnings.push_back(
        "the joint solve stopped at its iteration limit (" +
        std::to_string(SolverIterations(summary)) +
        ") before converging: the calibration, its sigma and the trajectory may be off; raise "
        "solver.max_iterations (the limit is solver.max_iterations times "
        "solver.outer_iterations)");
  }

  // 3. Observability, uncertainty and the result (the last solve's summary).
  const auto uncertainty_start = std::chrono::steady_clock::now();
  estimation::CovarianceOrdering ordering;  // one pattern for the posterior and the bound
  const estimation::BlockCovariance solved_covariance = PosteriorCovariance(
      blocks_estimated, joint.get(), problem.solver.num_threads, &result.warnings, {}, &ordering);
  const estimation::BlockCovariance covariance =
      WidenedForScatter(blocks_estimated, joint.get(), solved_covariance, options,
                        problem.solver.num_threads, &ordering, &result);
  result.batch.termination = summary.message;
  result.batch.final_cost = summary.final_cost;
  result.batch.calibration_per_iteration = {calibration};  // the last solve's
  io::CalibrationFile& file = result.calibration;
  file.solver["termination"] = summary.message;
  file.solver["iterations"] = std::to_string(SolverIterations(summary));
  file.solver["clock_pairing_solves"] = std::to_string(solves);
  file.solver["final_cost"] = std::to_string(summary.final_cost);
  if (use_gnss) file.solver["gnss_factors"] = std::to_string(placed.gnss_factors);
  RecordTiming(timing, true, &file);
  const sensors::Calibration solved = calibration;
  RecordPosterior(blocks_estimated, solved_covariance, covariance, solved, &result);
  RecordBoundAtTruth(options, blocks_estimated, &keyframes, &calibration, joint.get(),
                     problem.solver.num_threads, &result, {}, &ordering);
  const estimation::BlockObservability observability =
      Observe(dataset, options, blocks_estimated, solved_covariance, covariance, &result);
  result.seconds_uncertainty = SecondsSince(uncertainty_start);
  const auto holding_start = std::chrono::steady_clock::now();
  // The same budget as the first solve: pinning the held directions can move a long
  // dead-reckoned trajectory as far as the first solve did.
  const int budget = problem.solver.max_iterations * problem.solver.outer_iterations;
  SolveAgainAfterHolding(problem, blocks_estimated, observability, solved, &calibration,
                         joint.get(), &result, budget);
  if (sensor_factors.PairingChanges(keyframes, solved, calibration)) {
    // A clock held at its prior's centre has moved the keyframes onto other samples.
    joint = NewJointProblem(dataset, sensor_factors, &keyframes, &calibration);
    SolveAgainAfterHolding(problem, blocks_estimated, observability, solved, &calibration,
                           joint.get(), &result, budget);
  }
  result.seconds_after_holding = SecondsSince(holding_start);
  RequirePlausible(dataset, options, blocks_estimated, solved_covariance);
  const auto fixed_start = std::chrono::steady_clock::now();
  WarnOfFixedDirectionsTheDataMove(problem, dataset.sensors, options, use_wheel, use_gnss,
                                   &calibration, joint.get(), &result.warnings);
  result.seconds_uncertainty += SecondsSince(fixed_start);
  for (estimation::Keyframe& kf : keyframes) kf.q_W_I.normalize();
  RecordResidualsAfterSolve(joint.get(), &result.whitened_residuals);
  Conclude(dataset, problem, keyframes, &calibration, start, &result);
  return result;
}

}  // namespace pipeline
}  // namespace autocal
