#include "autocal/pipeline/offline_calibration.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iterator>
#include <optional>
#include <sstream>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/parallel_for.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/gnss_inertial_keyframes.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/output_files.h"
#include "autocal/io/tum_trajectory.h"
#include "autocal/pipeline/report_html.h"
#include "autocal/sensors/calibration_blocks.h"
#include "batch_warnings.h"
#include "calibration_steps.h"
#include "clock_initialization.h"
#include "keyframe_sweep_reader.h"
#include "mount_angles.h"
#include "problem_blocks.h"
#include "residual_groups.h"

namespace autocal {
namespace pipeline {

namespace {

// The batch solver's settings from the problem and the dataset.
estimation::LidarInertialBatchOptions BatchOptions(const io::Dataset& dataset,
                                                   const io::Problem& problem) {
  estimation::LidarInertialBatchOptions batch;
  batch.imu_noise = dataset.sensors.imu.noise;
  batch.gravity_m_s2 = dataset.sensors.imu.gravity_m_s2;
  batch.pairing.max_residuals_per_sweep = problem.lidar.max_points_per_sweep;
  batch.pairing.residual_voxel_m = problem.lidar.voxel_m;
  batch.point_loss = problem.loss.lidar;
  batch.outer_iterations = problem.solver.outer_iterations;
  batch.solver_iterations = problem.solver.max_iterations;
  batch.num_threads = problem.solver.num_threads;
  batch.estimate.extrinsic_rotation = Estimated(problem.calibration.T_I_L.rotation.mode);
  batch.estimate.extrinsic_translation = Estimated(problem.calibration.T_I_L.translation.mode);
  batch.estimate.time_offset = Estimated(problem.calibration.time_offset_lidar_imu_s.mode);
  return batch;
}

// The initializer's keyframes are in a gravity-aligned frame of their own; GNSS brings them
// into ENU. Where the LiDAR odometry followed the drive, a 4-DoF alignment of its track does
// (Eq. K3-K5), then its remaining drift is taken out of the positions (Eq. K5b), and true is
// returned. Where it did not (a featureless road, traffic moving with the car: its track then
// misses the fixes by metres or is too short to give the yaw), every state the initializer
// derived from that track is unusable: the keyframes are rebuilt from GNSS, the IMU and the
// problem's wheels (estimation/gnss_inertial_keyframes.h), a warning says so, and false is
// returned (the caller then starts the LiDAR blocks from their nominal values).
bool PlaceKeyframesInEnu(const io::Dataset& dataset, const io::Problem& problem,
                         const sensors::EnuConverter& enu, const sensors::Calibration& calibration,
                         const OfflineCalibrationOptions& options, bool use_wheel,
                         const TimingLimits& timing, std::vector<estimation::Keyframe>* keyframes,
                         std::vector<std::string>* warnings) {
  std::vector<estimation::Keyframe> aligned = *keyframes;
  std::string failure;
  try {
    estimation::GnssAlignmentOptions alignment;
    alignment.max_fix_gap_s = timing.max_fix_gap_s;
    const sensors::GnssFixes fixes =
        estimation::FixesOnImuClock(dataset.gnss, calibration.time_offset_gnss_imu_s);
    const estimation::GnssAlignment fit =
        estimation::AlignKeyframesToGnss(&aligned, fixes, enu, calibration.p_I_A, alignment);
    if (fit.rms_m <= options.max_odometry_to_gnss_rms_m) {
      // The drift the rigid alignment leaves (Eq. K5b), which the GNSS rows' Cauchy loss would
      // pull in only over several solver steps.
      estimation::OdometryDriftOptions drift;
      drift.max_fix_gap_s = timing.max_fix_gap_s;
      estimation::RemoveOdometryDrift(&aligned, fixes, enu, calibration.p_I_A, drift);
      *keyframes = std::move(aligned);
      return true;
    }
    failure = "its track misses the GNSS fixes by " + FormatFixed(fit.rms_m, 2) +
              " m RMS after alignment";
  } catch (const Error& e) {
    failure = e.what();
  }
  const estimation::GnssInertialKeyframes rebuilt = estimation::KeyframesFromGnssAndImu(
      keyframes, dataset.imu, StartWheelData(dataset, use_wheel), dataset.gnss, enu, calibration,
      GnssInertialStart(dataset, problem, timing));
  warnings->push_back(
      "the LiDAR odometry did not follow the drive (" + failure +
      "): the keyframes were "
      "rebuilt from GNSS and the IMU (" +
      std::to_string(rebuilt.placement.num_placed) + " on the fitted GNSS track, " +
      std::to_string(rebuilt.placement.num_bridged) +
      " bridged), and the LiDAR rotation, translation and time offset start from their nominal "
      "values");
  return false;
}

// The initializer on the keyframe sweeps, into result->initialization; throws when the drive
// cannot initialize the calibration.
void Initialize(const io::Dataset& dataset, const io::Problem& problem,
                const OfflineCalibrationOptions& options, lidar::SweepSource* sweeps,
                OfflineCalibrationResult* result) {
  Report(options, "initializing", 0.0, 0.0, 0.0);
  estimation::CalibrationInitializerOptions init_options = options.initializer;
  init_options.imu_noise = dataset.sensors.imu.noise;
  init_options.p_I_L_prior = result->nominal.p_I_L;
  init_options.odometry.num_threads = problem.solver.num_threads;
  // A drive without turns (a highway) cannot determine the rotation and offset: the nominal
  // values stand in, and the observability analysis then says what the solve could fix.
  init_options.fallback_q_I_L = result->nominal.q_I_L;
  init_options.fallback_time_offset_s = result->nominal.time_offset_lidar_imu_s;
  result->initialization = estimation::InitializeLidarImu(dataset.imu, sweeps, init_options);
  const estimation::CalibrationInitialization& init = result->initialization;
  if (!init.ok) {
    throw Error("dataset " + dataset.directory +
                ": the drive cannot initialize the calibration: " + Join(init.problems, "; "));
  }
  for (const std::string& fallback : init.fallbacks) {
    result->warnings.push_back("initialization: " + fallback);
  }
  Report(options, "initializing", 1.0, 0.0, 0.0);
}

// The keyframes of the batch solve and their sweeps.
struct BatchKeyframes {
  std::vector<estimation::SelectedSweep> sweeps;
  std::vector<estimation::Keyframe> keyframes;
  // The keyframes were rebuilt from GNSS and the IMU, and the LiDAR blocks restart from their
  // nominal values (PlaceInEnu).
  bool placed_without_lidar = false;
};

// The initializer's keyframes and their reduced sweeps, taken from the reader, with a warning
// for the sweeps it left out in IMU dropouts. Throws when fewer than two remain.
BatchKeyframes InitializerKeyframes(const io::Dataset& dataset, const io::Problem& problem,
                                    const estimation::CalibrationInitialization& init,
                                    internal::KeyframeSweepReader* sweeps,
                                    std::vector<std::string>* warnings) {
  BatchKeyframes out;
  for (size_t k = 0; k < init.keyframe_sweeps.size(); ++k) {
    out.sweeps.push_back(sweeps->TakeSelected(static_cast<size_t>(init.keyframe_sweeps[k])));
    out.keyframes.push_back(init.keyframes[k]);
  }
  const std::string dropout =
      ImuDropoutWarning(dataset.imu, init.keyframes_in_imu_dropouts, "the keyframe sweeps");
  if (!dropout.empty()) warnings->push_back(dropout);
  if (out.keyframes.size() < 2) {
    throw Error("problem " + problem.path + ": lidar.sweep_stride " +
                std::to_string(problem.lidar.sweep_stride) + " leaves " +
                std::to_string(out.keyframes.size()) +
                " keyframe(s) in the log; the solve needs two");
  }
  return out;
}

// W becomes the ENU frame at the first fix (`enu`): GNSS fixes position and yaw. Where the
// LiDAR odometry did not follow the drive, the keyframes are placed without it and the LiDAR
// blocks restart from their nominal values.
void PlaceInEnu(const io::Dataset& dataset, const io::Problem& problem,
                const OfflineCalibrationOptions& options, const sensors::EnuConverter& enu,
                bool use_wheel, const TimingLimits& timing, BatchKeyframes* keyframes,
                sensors::Calibration* calibration, OfflineCalibrationResult* result) {
  keyframes->placed_without_lidar =
      !PlaceKeyframesInEnu(dataset, problem, enu, *calibration, options, use_wheel, timing,
                           &keyframes->keyframes, &result->warnings);
  result->lidar_blocks_from_nominal = keyframes->placed_without_lidar;
  if (keyframes->placed_without_lidar) {
    calibration->q_I_L = result->nominal.q_I_L;
    calibration->p_I_L = result->nominal.p_I_L;
    calibration->time_offset_lidar_imu_s = result->nominal.time_offset_lidar_imu_s;
  }
  for (const sensors::GnssFix& fix : dataset.gnss) {
    result->gnss_positions_W.push_back(enu.ToEnu(fix.lat_deg, fix.lon_deg, fix.alt_m));
  }
}

// Keyframes that no LiDAR motion placed (rebuilt from GNSS and the IMU: the odometry did not
// follow the drive) leave the LiDAR rotation at its nominal value, which no turn checked: the
// batch searches about it within three of its prior's sigmas (docs/estimation.md, Eq. P13).
// Keyframes from the odometry line the sweeps up at whatever rotation they were built with, so
// a search there has nothing to score.
double StartingRotationSearchDeg(const BatchKeyframes& keyframes,
                                 const std::vector<estimation::EstimatedBlock>& blocks) {
  if (!keyframes.placed_without_lidar) return 0.0;
  const double range_deg = ThreeSigmaPriorDeg(blocks, sensors::CalibrationBlockId::kLidarRotation);
  return std::isfinite(range_deg) ? range_deg : 0.0;
}

// The batch solve with the problem's wheel and GNSS factors (with `enu`) and the blocks'
// priors; on its final problem the blocks' joint covariance, observability (Observe) and the
// solve after holding (Eq. C3). The whitened residuals before and after go to *result. The
// LiDAR's point RMS is the batch's, before that last solve.
void SolveBatch(const io::Dataset& dataset, const io::Problem& problem,
                const OfflineCalibrationOptions& options,
                const std::vector<estimation::EstimatedBlock>& blocks,
                const sensors::EnuConverter* enu, const TimingLimits& timing,
                BatchKeyframes* keyframes, sensors::Calibration* calibration,
                OfflineCalibrationResult* result) {
  estimation::LidarInertialBatchOptions batch_options = BatchOptions(dataset, problem);
  batch_options.hold_first_pose = enu == nullptr;
  batch_options.progress = [&](const estimation::LidarInertialBatchProgress& p) {
    const double per_iteration = p.elapsed_s / p.iteration;
    Report(options, "solving", static_cast<double>(p.iteration) / p.max_iterations, p.cost,
           per_iteration * (p.max_iterations - p.iteration));
  };
  geometry::RightQuaternionManifold quaternion_manifold;  // outlives every solve
  const bool use_wheel = problem.sensors.wheel && dataset.wheel_sample_count() > 0;
  SensorFactors sensor_factors{&dataset, &problem, &result->nominal,     use_wheel, enu != nullptr,
                               enu,      &blocks,  &quaternion_manifold, &timing};
  if (use_wheel) {
    sensor_factors.wheel_noise_scale =
        WheelNoiseScale(dataset, *calibration, result->nominal, &result->warnings);
  }
  estimation::PlanarRotationRows planar_rotation;
  sensor_factors.planar_rotation = &planar_rotation;
  bool first_problem = true;
  std::optional<estimation::GnssNoiseFromResiduals> gnss_noise;
  batch_options.add_factors = [&](ceres::Problem* p, std::vector<estimation::Keyframe>* kfs,
                                  sensors::Calibration* c) {
    // From the second problem on, the GNSS rows' noise about the last solve (Eq. N2).
    if (!first_problem && sensor_factors.use_gnss) {
      gnss_noise = MeasureGnssNoise(sensor_factors, kfs, c);
      sensor_factors.gnss_noise_scale = gnss_noise->Scale();
    }
    sensor_factors.Add(p, kfs, c);
    if (!first_problem) return;
    first_problem = false;
    for (auto& [sensor, rows] : WhitenedResidualsBySensor(p)) {
      result->whitened_residuals[sensor].before = std::move(rows);
    }
  };
  batch_options.compute_covariance = false;  // the joint one below covers every block
  estimation::BlockObservability observability;
  batch_options.inspect_final_problem = [&](ceres::Problem* p) {
    if (sensor_factors.use_gnss && !gnss_noise) {
      // One outer iteration: the fixes' scatter is measured but cannot weigh them any more.
      gnss_noise = MeasureGnssNoise(sensor_factors, &keyframes->keyframes, calibration);
    }
    const auto uncertainty_start = std::chrono::steady_clock::now();
    const estimation::ScaledInformation lidar = LidarSandwich(p);
    result->calibration.residuals["lidar"]["sandwich_kappa"] = 1.0 / lidar.scale;
    estimation::CovarianceOrdering ordering;  // one pattern for the posterior and the bound
    const estimation::BlockCovariance solved_covariance = PosteriorCovariance(
        blocks, p, problem.solver.num_threads, &result->warnings, lidar, &ordering);
    const estimation::BlockCovariance covariance = WidenedForScatter(
        blocks, p, solved_covariance, options, problem.solver.num_threads, &ordering, result);
    const sensors::Calibration solved = *calibration;
    RecordPosterior(blocks, solved_covariance, covariance, solved, result);
    RecordBoundAtTruth(options, blocks, &keyframes->keyframes, calibration, p,
                       problem.solver.num_threads, result, lidar, &ordering);
    observability = Observe(dataset, options, blocks, solved_covariance, covariance, result);
    result->seconds_uncertainty = SecondsSince(uncertainty_start);
    const auto holding_start = std::chrono::steady_clock::now();
    SolveAgainAfterHolding(problem, blocks, observability, solved, calibration, p, result);
    result->seconds_after_holding = SecondsSince(holding_start);
    RequirePlausible(dataset, options, blocks, solved_covariance);
    const auto fixed_start = std::chrono::steady_clock::now();
    WarnOfFixedDirectionsTheDataMove(problem, dataset.sensors, options, use_wheel, enu != nullptr,
                                     calibration, p, &result->warnings);
    result->seconds_uncertainty += SecondsSince(fixed_start);
    RecordResidualsAfterSolve(p, &result->whitened_residuals);
  };
  batch_options.starting_rotation_search_deg = StartingRotationSearchDeg(*keyframes, blocks);
  sensors::Calibration start = *calibration;
  Report(options, "solving", 0.0, 0.0, 0.0);
  result->batch = estimation::SolveLidarInertialBatch(
      dataset.imu, keyframes->sweeps, &keyframes->keyframes, calibration, batch_options);
  const estimation::LidarInertialBatchReport& batch = result->batch;
  if (batch.rotation_search.searched) start.q_I_L = batch.rotation_search.q_I_L_start;
  for (const std::string& warning : {RotationSearchWarning(batch.rotation_search),
                                     StillMovingWarning(batch, start, blocks, observability)}) {
    if (!warning.empty()) result->warnings.push_back(warning);
  }
  io::CalibrationFile& file = result->calibration;
  if (gnss_noise) {
    RecordGnssNoiseScale(sensor_factors.gnss_noise_scale, &file);
    std::string warning = GnssNoiseWarning(*gnss_noise);
    if (!warning.empty() && !(gnss_noise->Scale() == sensor_factors.gnss_noise_scale)) {
      warning +=
          "; but the solve ended after its first outer iteration, before the scale could weigh "
          "them: raise solver.outer_iterations";
    }
    if (!warning.empty()) result->warnings.push_back(warning);
    WhitenGnssRowsBeforeAlike(sensor_factors.gnss_noise_scale, &result->whitened_residuals);
  }
  file.solver["termination"] = batch.termination;
  file.solver["outer_iterations"] = std::to_string(batch.outer_iterations);
  file.solver["outer_iterations_converged"] = batch.converged ? "true" : "false";
  file.solver["final_cost"] = std::to_string(batch.final_cost);
  file.residuals["lidar"]["rms_m"] = batch.point_rms_m;
  file.residuals["lidar"]["sigma_m"] = batch.point_sigma_m;
  file.residuals["lidar"]["points_downweighted_by_loss"] = batch.points_downweighted_by_loss;
  file.residuals["lidar"]["rms_m_not_downweighted"] = batch.point_rms_not_downweighted_m;
  file.residuals["lidar"]["associated_points"] = batch.associated_points;
  RecordPlanarRotation(planar_rotation, &file);
}

// `file` without the wall-clock entries of its solver summary ("seconds", "seconds_*"): they
// go to timings.yaml.
io::CalibrationFile WithoutTimings(io::CalibrationFile file) {
  for (auto it = file.solver.begin(); it != file.solver.end();) {
    it = it->first.rfind("seconds", 0) == 0 ? file.solver.erase(it) : std::next(it);
  }
  return file;
}

// calibration_per_iteration.csv: the iteration (from 1), then every block's values in table
// order.
std::string PerIterationCsv(const std::vector<sensors::Calibration>& history) {
  std::ostringstream csv;
  csv << "iteration";
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    for (const std::string& column : sensors::IterationColumns(block)) csv << ',' << column;
  }
  csv << '\n' << std::setprecision(12);
  for (size_t i = 0; i < history.size(); ++i) {
    csv << i + 1;
    for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
      const double* values = block.const_values(history[i]);
      for (int k = 0; k < block.ambient_size; ++k) csv << ',' << values[k];
    }
    csv << '\n';
  }
  return csv.str();
}

// Wall-clock seconds of the run's stages. They differ from run to run, so they live in
// timings.yaml, apart from the values: identical runs give identical calibration.yaml files.
std::string TimingsYaml(const OfflineCalibrationResult& result) {
  std::ostringstream out;
  out << "# autocal_calibrate wall-clock seconds (differ from run to run)\n"
      << "seconds_total: " << result.seconds_total << "\n"
      << "seconds_loading: " << result.seconds_loading << "\n"
      << "seconds_initialization: " << result.seconds_initialization << "\n"
      << "seconds_solve: " << result.seconds_solve << "\n"
      << "seconds_association: " << result.batch.seconds_association << "\n"
      << "seconds_ceres: " << result.batch.seconds_solver << "\n"
      << "seconds_uncertainty: " << result.seconds_uncertainty << "\n"
      << "seconds_after_holding: " << result.seconds_after_holding << "\n";
  return out.str();
}

OfflineCalibrationResult CalibrateWithLidar(const io::Dataset& dataset, const io::Problem& problem,
                                            const OfflineCalibrationOptions& options,
                                            std::chrono::steady_clock::time_point start) {
  OfflineCalibrationResult result;
  result.nominal = dataset.sensors.nominal_calibration;
  result.prior_centre = result.nominal;

  // 1-2. Initialization on the keyframe sweeps, read as the odometry reaches them (no
  //      hand-measured guess needed); each is kept reduced for the batch.
  const double seconds_before = SecondsSince(start);
  internal::KeyframeSweepReader sweeps(
      dataset, problem.lidar.sweep_stride, BatchOptions(dataset, problem).pairing,
      problem.solver.num_threads,
      [&](double fraction) { Report(options, "initializing", fraction, 0.0, 0.0); });
  Initialize(dataset, problem, options, &sweeps, &result);
  // Loading: the log's files before, and the sweeps' reading and reduction during it.
  result.seconds_loading = seconds_before + sweeps.seconds_reading();
  result.seconds_initialization = SecondsSince(start) - result.seconds_loading;

  // 3. Batch solve from the initializer's calibration (fixed blocks keep the nominal value),
  //    with the wheel and GNSS factors and the priors of the problem.
  sensors::Calibration calibration =
      StartFromInitializer(result.nominal, problem.calibration, result.initialization);
  const ClockInitialization clocks =
      InitializeClockOffsets(dataset, problem, &calibration, &result.warnings);
  result.wheel_clock_initialization = clocks.wheel;
  result.gnss_clock_initialization = clocks.gnss;
  BatchKeyframes keyframes =
      InitializerKeyframes(dataset, problem, result.initialization, &sweeps, &result.warnings);
  const bool use_wheel = problem.sensors.wheel && dataset.wheel_sample_count() > 0;
  const bool use_gnss = problem.sensors.gnss && !dataset.gnss.empty();
  const TimingLimits timing = DeriveTimingLimits(dataset, problem, use_wheel, use_gnss);
  std::optional<sensors::EnuConverter> enu;
  if (use_gnss) {
    enu = sensors::EnuConverter::AtFirstFix(dataset.gnss);
    PlaceInEnu(dataset, problem, options, *enu, use_wheel, timing, &keyframes, &calibration,
               &result);
  }
  const std::vector<estimation::EstimatedBlock> blocks_estimated =
      EstimatedBlocks(problem, dataset.sensors, options, use_wheel, use_gnss, &calibration);
  SolveBatch(dataset, problem, options, blocks_estimated, enu ? &*enu : nullptr, timing, &keyframes,
             &calibration, &result);
  RecordTiming(timing, false, &result.calibration);

  // 4. (Observability and uncertainty came with the final problem, in SolveBatch.) The result.
  RequireLidarFactors(dataset, problem, keyframes.keyframes.size(), result);
  Conclude(dataset, problem, keyframes.keyframes, &calibration, start, &result);
  return result;
}

}  // namespace

OfflineCalibrationResult CalibrateDataset(const io::Dataset& input, const io::Problem& problem,
                                          const OfflineCalibrationOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  io::ValidateProblemForDataset(problem, input);
  CheckScatterOptions(options);
  std::vector<std::string> noise_warnings;
  std::optional<io::Dataset> storage;
  const io::Dataset& dataset = WithImuNoiseFromData(input, &storage, &noise_warnings);
  OfflineCalibrationResult result = problem.sensors.lidar
                                        ? CalibrateWithLidar(dataset, problem, options, start)
                                        : CalibrateWithoutLidar(dataset, problem, options, start);
  result.warnings.insert(result.warnings.begin(), noise_warnings.begin(), noise_warnings.end());
  return result;
}

void WriteCalibrationResult(const std::string& directory, const OfflineCalibrationResult& result,
                            const io::RunStatus* status) {
  io::StagedDirectory out(directory, io::OutputKind::kResult);
  io::WriteCalibrationYaml(out.File("calibration.yaml"), WithoutTimings(result.calibration));
  io::WriteTumTrajectory(out.File("trajectory.tum"), result.trajectory);
  io::WriteFileAtomically(out.File("calibration_per_iteration.csv"),
                          PerIterationCsv(result.batch.calibration_per_iteration));
  io::WriteFileAtomically(out.File("timings.yaml"), TimingsYaml(result));
  io::WriteFileAtomically(out.File("report.html"), CalibrationReportHtml(result));
  io::WriteWarningsFile(out.File("warnings.txt"), result.warnings);
  if (status != nullptr) io::WriteRunStatus(out.File("status.yaml"), *status);
  out.Commit();
}

std::string FormatCalibrationValues(const io::CalibrationFile& file) {
  const sensors::Calibration& c = file.value;
  const io::CalibrationUncertainty& u = file.uncertainty;
  std::ostringstream out;
  out << std::fixed;
  // One line per estimated block (those with a sigma): value, sigma, observable per axis.
  const auto flags = [](const std::vector<bool>& f, size_t first, size_t n) {
    std::string text;
    for (size_t i = 0; i < n; ++i) {
      const bool yes = f.empty() ? true : f.size() == 1 ? f[0] : f[first + i];
      text += yes ? " yes" : " no";
    }
    return text;
  };
  const auto line = [&](const std::string& name, const Eigen::VectorXd& value,
                        const Eigen::VectorXd& sigma, const std::string& observable,
                        int precision) {
    out << std::left << std::setw(34) << name << std::right << std::setprecision(precision);
    for (Eigen::Index i = 0; i < value.size(); ++i) out << ' ' << std::setw(9) << value(i);
    out << "   sigma";
    for (Eigen::Index i = 0; i < sigma.size(); ++i) out << ' ' << std::setw(7) << sigma(i);
    out << "   observable" << observable << '\n';
  };
  const auto scalar = [&](const std::string& name, double value, const io::ScalarBlockInfo& info,
                          double scale, int precision) {
    if (!info.sigma) return;
    line(name, Eigen::VectorXd::Constant(1, value * scale),
         Eigen::VectorXd::Constant(1, *info.sigma * scale),
         info.observable.value_or(true) ? " yes" : " no", precision);
  };
  // Rotations as roll, pitch, yaw of the mounting (mount_angles.h), with those angles' sigma
  // and observability: `mount` is R_I_L for the LiDAR (its tangent about the LiDAR's axes),
  // R_V_I for the IMU in the vehicle (about the vehicle's).
  const auto pose = [&](const std::string& name, const std::string& rotation_name,
                        const Eigen::Quaterniond& mount, bool about_parent_axes,
                        const Eigen::Vector3d& p, const io::PoseBlockInfo& info,
                        int rotation_precision) {
    if (info.sigma_rot_deg) {
      const std::vector<bool> rotation_flags =
          info.observable.size() > 1
              ? std::vector<bool>(info.observable.begin(), info.observable.begin() + 3)
              : info.observable;
      const DisplayedAngles angles =
          DisplayedAngleUncertainty(mount, about_parent_axes, *info.sigma_rot_deg, rotation_flags);
      line(rotation_name, DisplayRollPitchYawDeg(mount, rotation_precision), angles.sigma_deg,
           flags(angles.observable, 0, 3), rotation_precision);
    }
    if (info.sigma_p_m) {
      line(name + " translation (mm)", p * 1e3, *info.sigma_p_m * 1e3, flags(info.observable, 3, 3),
           1);
    }
  };
  pose("T_I_L", "T_I_L roll pitch yaw (deg)", c.q_I_L, false, c.p_I_L, u.T_I_L, 4);
  scalar("time offset lidar->imu (ms)", c.time_offset_lidar_imu_s, u.time_offset_lidar_imu_s, 1e3,
         3);
  scalar("left rear wheel radius (mm)", c.wheel_radius_left_m, u.wheel_radius_left_m, 1e3, 3);
  scalar("right rear wheel radius (mm)", c.wheel_radius_right_m, u.wheel_radius_right_m, 1e3, 3);
  scalar("track width (mm)", c.track_width_m, u.track_width_m, 1e3, 1);
  scalar("left rear wheel speed scale (%)", c.wheel_speed_scale_left, u.wheel_speed_scale_left,
         100.0, 3);
  scalar("right rear wheel speed scale (%)", c.wheel_speed_scale_right, u.wheel_speed_scale_right,
         100.0, 3);
  scalar("odometry speed scale (%)", c.odometry_speed_scale, u.odometry_speed_scale, 100.0, 3);
  scalar("effective track (mm)", c.effective_track_m, u.effective_track_m, 1e3, 1);
  scalar("wheel clock offset (ms)", c.time_offset_wheel_imu_s, u.time_offset_wheel_imu_s, 1e3, 1);
  scalar("GNSS clock offset (ms)", c.time_offset_gnss_imu_s, u.time_offset_gnss_imu_s, 1e3, 1);
  pose("T_I_V", "IMU mount roll pitch yaw (deg)", ImuMountInVehicle(c.q_I_V), true, c.p_I_V,
       u.T_I_V, 3);
  if (u.p_I_A_m.sigma) {
    line("GNSS lever arm p_I_A (mm)", c.p_I_A * 1e3, *u.p_I_A_m.sigma * 1e3,
         flags(u.p_I_A_m.observable, 0, 3), 1);
  }
  return out.str();
}

std::string FormatCalibrationSummary(const OfflineCalibrationResult& result) {
  std::ostringstream out;
  out << std::fixed << FormatCalibrationValues(result.calibration);
  const estimation::LidarInertialBatchReport& batch = result.batch;
  if (batch.associated_points > 0) {
    out << "LiDAR residual RMS (m): " << std::setprecision(4) << batch.point_rms_m << " over "
        << batch.associated_points << " points; point sigma (m): " << batch.point_sigma_m;
    if (batch.points_downweighted_by_loss > 0) {
      out << "; the loss down-weighted " << batch.points_downweighted_by_loss
          << " points (the others' RMS " << batch.point_rms_not_downweighted_m << " m)";
    }
    out << "\n";
  }
  // The whitened RMS per sensor, as Conclude put it into the result's residual statistics.
  for (const auto& [sensor, statistics] : result.calibration.residuals) {
    const auto rms = statistics.find("whitened_rms");
    const auto rows = statistics.find("rows");
    if (rms == statistics.end() || rows == statistics.end()) continue;
    out << sensor << " whitened residual RMS: " << std::setprecision(3) << rms->second << " over "
        << std::setprecision(0) << rows->second << " rows";
    const auto outliers = statistics.find("outlier_rows");
    const auto without = statistics.find("whitened_rms_without_outliers");
    const auto robust = statistics.find("whitened_robust_sigma");
    if (outliers != statistics.end() && without != statistics.end() && robust != statistics.end()) {
      out << " (" << std::setprecision(3) << without->second << " without the "
          << std::setprecision(0) << outliers->second << " beyond " << kOutlierRobustSigmas
          << " robust sigmas; robust sigma " << std::setprecision(3) << robust->second << ")";
    }
    const auto factors = statistics.find("factors");
    const auto downweighted = statistics.find("factors_downweighted_by_loss");
    const auto rest = statistics.find("whitened_rms_not_downweighted");
    if (factors != statistics.end() && downweighted != statistics.end() &&
        rest != statistics.end() && downweighted->second > 0.0) {
      out << "; the loss down-weighted " << std::setprecision(0) << downweighted->second << " of "
          << factors->second << " factors (the others' RMS " << std::setprecision(3) << rest->second
          << ")";
    }
    out << "\n";
  }
  out << std::setprecision(1) << result.trajectory.size() << " keyframes; " << result.seconds_total
      << " s (loading " << result.seconds_loading << " s, initialization "
      << result.seconds_initialization << " s, solve " << result.seconds_solve << " s";
  if (batch.outer_iterations > 0) {
    out << ": " << batch.outer_iterations << " outer iterations"
        << (batch.converged ? "" : " (stopped before converging)") << ", association "
        << batch.seconds_association << " s, Ceres " << batch.seconds_solver << " s";
  } else if (batch.seconds_solver > 0.0) {  // without the LiDAR: Ceres' solves alone
    out << ": Ceres " << batch.seconds_solver << " s";
  }
  out << ")\n";
  for (const std::string& warning : result.warnings) out << "warning: " << warning << '\n';
  return out.str();
}

}  // namespace pipeline
}  // namespace autocal
