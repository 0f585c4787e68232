#include "autocal/pipeline/online_estimation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/parallel_for.h"
#include "autocal/common/time.h"
#include "autocal/estimation/gnss_inertial_keyframes.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/estimation/sliding_window_blocks.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/tum_trajectory.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sensors/calibration_blocks.h"
#include "batch_warnings.h"
#include "calibration_steps.h"
#include "clock_initialization.h"
#include "online_judgement.h"
#include "online_without_lidar.h"
#include "problem_blocks.h"
#include "sweep_reader.h"
#include "window_settings.h"

namespace autocal {
namespace pipeline {

namespace {

// A keyframe as a trajectory sample (pose and velocity).
io::TrajectorySample TrajectorySampleOf(const estimation::SlidingWindowState& x) {
  io::TrajectorySample s;
  s.t_ns = x.t_ns;
  s.T_W_I = geometry::Pose3d(x.q_W_I, x.p_W_I);
  s.v_W_I = x.v_W_I;
  return s;
}

// With GNSS, the start the window is given (docs/sliding_window.md, "Streaming a dataset": GNSS yaw
// of the extrinsic). The initializer's IMU orientations are its LiDAR odometry's turned by its
// q_I_L, whose rotation about the vertical planar driving hardly determines (1.0 deg off on the 60
// s urban log): every aligned keyframe's yaw was off by 1.4 deg, and the window's first keyframes
// kept that. The GNSS-inertial solve over the same keyframes (IMU, fixes, wheels) gives each IMU
// orientation from gravity and the track's accelerations instead (0.17 deg at the start of that
// log, 0.05 deg later). Returns that solve's first keyframe and its covariance and, with
// estimate_q_I_L, in *q_I_L the extrinsic turned about the IMU's vertical by the median of
//   phi_k = u_k . Log(R_W_I,gnss_k^T R_W_I,aligned_k),  u_k = R_W_I,gnss_k^T z_W,
// so that the LiDAR keeps the orientation its odometry gave it: R_W_L = R_W_I R_I_L with
// R_I_L <- Exp(phi u) R_I_L, where the aligned keyframes' R_W_I = R_W_L R_I_L^T.
struct GnssStart {
  estimation::Keyframe keyframe;
  estimation::GnssInertialKeyframes solve;  // its first_covariance, its fixes' std scale
};
GnssStart StartFromGnssAndImu(const io::Dataset& dataset, const estimation::WheelData& wheel,
                              estimation::GnssInertialKeyframesOptions options,
                              const sensors::EnuConverter& enu,
                              const std::vector<estimation::Keyframe>& aligned, bool estimate_q_I_L,
                              const sensors::Calibration& calibration, Eigen::Quaterniond* q_I_L) {
  std::vector<estimation::Keyframe> refined = aligned;
  options.first_keyframe_covariance = true;
  GnssStart out;
  out.solve = estimation::KeyframesFromGnssAndImu(&refined, dataset.imu, wheel, dataset.gnss, enu,
                                                  calibration, options);
  if (estimate_q_I_L) {
    std::vector<double> phi;
    Eigen::Vector3d up_I = Eigen::Vector3d::Zero();
    for (size_t k = 0; k < refined.size(); ++k) {
      const Eigen::Vector3d u = refined[k].q_W_I.conjugate() * Eigen::Vector3d::UnitZ();
      phi.push_back(u.dot(geometry::Log(refined[k].q_W_I.conjugate() * aligned[k].q_W_I)));
      up_I += u;
    }
    std::nth_element(phi.begin(), phi.begin() + phi.size() / 2, phi.end());
    const Eigen::Quaterniond turn(Eigen::AngleAxisd(phi[phi.size() / 2], up_I.normalized()));
    *q_I_L = (turn * calibration.q_I_L).normalized();
  }
  out.keyframe = refined.front();
  return out;
}

// Throws one autocal::Error for a problem that has neither the LiDAR nor GNSS, or invalid
// options.
void CheckOnlineInputs(const io::Dataset& dataset, const io::Problem& problem,
                       const OnlineEstimationOptions& options) {
  if (!problem.sensors.lidar && (!problem.sensors.gnss || dataset.gnss.empty())) {
    throw Error("problem " + problem.path +
                ": the online estimator without the LiDAR needs GNSS (sensors.gnss and " +
                "gnss.csv): its start is placed on the GNSS track");
  }
  // Spans are turned into int64 nanoseconds and added to stamps: beyond 1e9 s (31 years) the
  // count overflows and a span of the log becomes none.
  constexpr double kMaxSpanS = 1e9;
  if (!(options.keyframe_period_without_lidar_s >= 0.0) ||
      !(options.keyframe_period_without_lidar_s <= kMaxSpanS)) {
    throw Error(
        "OnlineEstimationOptions: keyframe_period_without_lidar_s must be within [0, 1e9] "
        "s, got " +
        FormatShort(options.keyframe_period_without_lidar_s));
  }
  if (!(options.initialization_duration_s <= kMaxSpanS)) {
    throw Error(
        "OnlineEstimationOptions: initialization_duration_s must be a positive number of "
        "seconds up to 1e9, got " +
        FormatShort(options.initialization_duration_s));
  }
  if (!(options.initialization_duration_s > 0.0) || !(options.max_odometry_to_gnss_rms_m > 0.0) ||
      !(options.initial_position_sigma_with_gnss_m > 0.0) ||
      !(options.initial_accel_bias_sigma_with_gnss_m_s2 > 0.0) ||
      options.initializer_sweep_stride < 1) {
    throw Error(
        "OnlineEstimationOptions: initialization_duration_s, max_odometry_to_gnss_rms_m, "
        "initial_position_sigma_with_gnss_m, initial_accel_bias_sigma_with_gnss_m_s2 "
        "and initializer_sweep_stride must be positive");
  }
  const double significance = options.scatter_significance;
  if (options.scatter_stretches < 0 || options.scatter_stretches == 1 ||
      options.scatter_stretches == 2 || !(significance > 0.0) || !(significance < 1.0)) {
    throw Error(
        "OnlineEstimationOptions: scatter_stretches must be 0 (no test) or at least 3, and "
        "scatter_significance in (0, 1); got " +
        std::to_string(options.scatter_stretches) + " and " + std::to_string(significance));
  }
}

// The end of the log's first initialization_duration_s: the initializer's sweeps are those
// stamped before it.
int64_t InitializationEndNs(const io::Dataset& dataset, const OnlineEstimationOptions& options) {
  return dataset.lidar_sweeps.front().t_ns + SecondsToNs(options.initialization_duration_s);
}

// The sweeps of the log's first initialization_duration_s and the initializer's result on
// every initializer_sweep_stride-th of them (lent to it: moved there and back).
struct InitialSeconds {
  std::vector<lidar::LidarSweep> sweeps;
  estimation::CalibrationInitialization init;
  size_t start_sweep = 0;  // in dataset.lidar_sweeps: the sweep of init's first keyframe
};
// A drive without turns (a highway) cannot determine the rotation and offset. With GNSS
// (use_gnss) the nominal values stand in, with a warning each in *warnings, and StartWindow
// checks the odometry against the fixes; without, nothing would tell a failed start, and the
// initializer's problems are an error.
InitialSeconds InitializeOnFirstSeconds(const io::Dataset& dataset, const io::Problem& problem,
                                        const OnlineEstimationOptions& options, bool use_gnss,
                                        std::vector<std::string>* warnings) {
  const int64_t init_end_ns = InitializationEndNs(dataset, options);
  size_t num_init_sweeps = 0;
  while (num_init_sweeps < dataset.lidar_sweeps.size() &&
         dataset.lidar_sweeps[num_init_sweeps].t_ns < init_end_ns) {
    ++num_init_sweeps;
  }
  InitialSeconds out;
  std::vector<lidar::LidarSweep>& sweeps = out.sweeps;
  sweeps.resize(num_init_sweeps);
  ParallelFor(0, static_cast<int64_t>(num_init_sweeps), problem.solver.num_threads,
              [&](int64_t begin, int64_t end, int) {
                for (int64_t i = begin; i < end; ++i) {
                  sweeps[static_cast<size_t>(i)] = dataset.LoadSweep(static_cast<size_t>(i));
                }
              });
  estimation::CalibrationInitializerOptions init_options = options.initializer;
  init_options.imu_noise = dataset.sensors.imu.noise;
  init_options.p_I_L_prior = dataset.sensors.nominal_calibration.p_I_L;
  if (use_gnss) {
    init_options.fallback_q_I_L = dataset.sensors.nominal_calibration.q_I_L;
    init_options.fallback_time_offset_s =
        dataset.sensors.nominal_calibration.time_offset_lidar_imu_s;
  }
  const size_t stride = static_cast<size_t>(options.initializer_sweep_stride);
  std::vector<lidar::LidarSweep> init_sweeps;
  for (size_t i = 0; i < sweeps.size(); i += stride) init_sweeps.push_back(std::move(sweeps[i]));
  out.init = estimation::InitializeLidarImu(dataset.imu, init_sweeps, init_options);
  for (size_t k = 0; k < init_sweeps.size(); ++k) sweeps[k * stride] = std::move(init_sweeps[k]);
  if (!out.init.ok || out.init.keyframes.empty()) {
    throw Error("dataset " + dataset.directory +
                ": the initializer could not start the window "
                "from the first " +
                FormatShort(options.initialization_duration_s) +
                " s: " + Join(out.init.problems, "; "));
  }
  for (const std::string& fallback : out.init.fallbacks) {
    warnings->push_back("initialization: " + fallback);
  }
  out.start_sweep = static_cast<size_t>(out.init.keyframe_sweeps.front()) * stride;
  return out;
}

// Moves the initializer's keyframes into W by the 4-DoF alignment to the fixes. Returns why
// its LiDAR odometry did not follow the drive (the track misses the fixes by more than
// max_rms_m after the alignment, or spans too little to give the yaw), empty when it did.
std::string OdometryMissesGnss(const io::Dataset& dataset, const sensors::EnuConverter& enu,
                               const TimingLimits& timing, const Eigen::Vector3d& p_I_A,
                               double max_rms_m, std::vector<estimation::Keyframe>* keyframes) {
  estimation::GnssAlignmentOptions alignment;
  alignment.max_fix_gap_s = timing.max_fix_gap_s;
  try {
    const double rms_m =
        estimation::AlignKeyframesToGnss(keyframes, dataset.gnss, enu, p_I_A, alignment).rms_m;
    if (rms_m <= max_rms_m) return "";
    return "its track misses the GNSS fixes by " + FormatFixed(rms_m, 2) + " m RMS after alignment";
  } catch (const Error& e) {
    return e.what();
  }
}

// The window's starting calibration (the initializer's LiDAR blocks where estimated) and
// first keyframe.
struct WindowStart {
  sensors::Calibration calibration;
  estimation::Keyframe keyframe;
};

// The calibration the offline batch finds on the log's first initialization_duration_s, as the
// window's start where the initializer's LiDAR odometry did not follow the drive (a highway).
// From the nominal values the window did not find the extrinsic there: on 30 s highway drives
// its LiDAR pitch ended 3.8 and 8.3 deg off at a stated 0.12 deg, while the batch's
// coarse-to-fine association ends within its sigmas (docs/sliding_window.md, "Streaming a
// dataset"). One thread, so that the start does not depend on the thread count. Where the
// batch searched a nominal LiDAR rotation and moved it, a warning in *warnings says so (its
// other warnings are the first seconds' and the window's own report stands for the result).
// Throws autocal::Error, starting with `why` the initializer could not start the window, when
// the batch fails (a ParseError as it is).
sensors::Calibration CalibrateFirstSeconds(const io::Dataset& dataset, const io::Problem& problem,
                                           const OnlineEstimationOptions& options,
                                           const std::string& why,
                                           std::vector<std::string>* warnings) {
  // The initializer's seconds, without the instant that ends them (as its sweeps).
  const io::Dataset first = io::DatasetUntil(dataset, InitializationEndNs(dataset, options) - 1);
  io::Problem single_thread = problem;
  single_thread.solver.num_threads = 1;
  OfflineCalibrationOptions offline;
  offline.max_odometry_to_gnss_rms_m = options.max_odometry_to_gnss_rms_m;
  try {
    const OfflineCalibrationResult result = CalibrateDataset(first, single_thread, offline);
    const std::string searched = RotationSearchWarning(result.batch.rotation_search);
    if (!searched.empty()) warnings->push_back("the start's offline calibration: " + searched);
    return result.calibration.value;
  } catch (const ParseError&) {
    throw;
  } catch (const Error& e) {
    throw Error(why + ", and the offline calibration of those seconds that would start the " +
                "window failed: " + e.what());
  }
}

// With GNSS, W is the ENU frame at the first fix: the initializer's gravity-aligned keyframes
// are moved there by the 4-DoF alignment, the first one refined by StartFromGnssAndImu, and
// *window_options gets the ENU origin and the initial state's covariance (SetGnssStart). Where
// the initializer's LiDAR odometry did not follow the drive (its track misses the fixes, or is
// too short to give the yaw), the calibration and the window's prior centres come from
// CalibrateFirstSeconds, the GNSS-inertial solve alone places the first keyframe, and a
// warning in *warnings says so.
WindowStart StartWindow(const io::Dataset& dataset, const io::Problem& problem,
                        const OnlineEstimationOptions& options, const TimingLimits& timing,
                        const estimation::CalibrationInitialization& init, bool use_wheel,
                        bool use_gnss, estimation::SlidingWindowOptions* window_options,
                        std::vector<std::string>* warnings) {
  WindowStart out;
  out.calibration =
      StartFromInitializer(dataset.sensors.nominal_calibration, problem.calibration, init);
  std::vector<estimation::Keyframe> keyframes = init.keyframes;
  const std::string dropout = ImuDropoutWarning(dataset.imu, init.keyframes_in_imu_dropouts,
                                                "the initializer's keyframe sweeps");
  if (!dropout.empty()) warnings->push_back(dropout);
  if (use_gnss) {
    const sensors::EnuConverter enu = sensors::EnuConverter::AtFirstFix(dataset.gnss);
    const std::string failure = OdometryMissesGnss(dataset, enu, timing, out.calibration.p_I_A,
                                                   options.max_odometry_to_gnss_rms_m, &keyframes);
    if (!failure.empty()) {
      const std::string why =
          "the initializer's LiDAR odometry could not be aligned to the GNSS fixes of the first " +
          FormatShort(options.initialization_duration_s) + " s (" + failure + ")";
      // The priors keep their sigmas and centre on the batch's values: centred at the nominal
      // ones, they pulled every block back there before the first sweeps paired.
      out.calibration = CalibrateFirstSeconds(dataset, problem, options, why, warnings);
      window_options->calibration_prior.mean = out.calibration;
      warnings->push_back(why +
                          ": the window starts from GNSS and the IMU, and its calibration from "
                          "the offline calibration of those seconds");
    }
    // The start's small solve on one thread: Ceres sums cost and gradient per thread, and a
    // stopping decision that moved with the count would move the whole stream's estimate.
    estimation::GnssInertialKeyframesOptions gnss_start =
        GnssInertialStart(dataset, problem, timing);
    gnss_start.num_threads = 1;
    const GnssStart start =
        StartFromGnssAndImu(dataset, StartWheelData(dataset, use_wheel), gnss_start, enu, keyframes,
                            failure.empty() && Estimated(problem.calibration.T_I_L.rotation.mode),
                            out.calibration, &out.calibration.q_I_L);
    keyframes.front() = start.keyframe;
    SetGnssStart(enu, start.solve, options, window_options, warnings);
  }
  // The initializer's keyframes use its time offset; the window's keyframe time rule
  // (KeyframeTimeOf) uses the calibration's: the same value, the nominal one or the batch's.
  out.keyframe = keyframes.front();
  return out;
}

// One datum of the log at its arrival time: which stream, which sample (for a keyframe time,
// none: the time is the arrival's).
enum class Source { kImu, kWheel, kWheelSpeeds, kOdometry, kGnss, kSweep, kKeyframeTime };
struct Arrival {
  int64_t t_ns;
  Source source;
  size_t index;
};

// The LiDAR's sweep period: sensors.yaml's rate, else 10 Hz.
double SweepPeriodS(const io::Dataset& dataset) {
  return dataset.sensors.lidar ? 1.0 / dataset.sensors.lidar->rate_hz : 0.1;
}

// Every datum after the initial state at t0_ns in arrival order: a sweep arrives when its last
// point is measured (its stamp plus the sweep period), IMU samples from the last one at or
// before t0_ns on, the sweeps from first_sweep on (the one before it made the initial state, and
// those before that lie before it). Without
// the LiDAR (keyframe_period_ns > 0) a keyframe time every period after t0_ns up to the last IMU
// sample takes the sweeps' place.
std::vector<Arrival> ArrivalOrder(const io::Dataset& dataset, bool use_wheel, bool use_gnss,
                                  int64_t t0_ns, size_t first_sweep, int64_t keyframe_period_ns) {
  std::vector<Arrival> out;
  for (size_t i = 0; i < dataset.imu.size(); ++i) {
    const bool needed = dataset.imu[i].t_ns > t0_ns ||
                        (i + 1 < dataset.imu.size() && dataset.imu[i + 1].t_ns > t0_ns);
    if (needed) out.push_back({dataset.imu[i].t_ns, Source::kImu, i});
  }
  for (size_t i = 0; use_wheel && i < dataset.wheel.size(); ++i) {
    if (dataset.wheel[i].t_ns > t0_ns) out.push_back({dataset.wheel[i].t_ns, Source::kWheel, i});
  }
  for (size_t i = 0; use_wheel && i < dataset.wheel_speeds.size(); ++i) {
    const int64_t t = dataset.wheel_speeds[i].t_ns;
    if (t > t0_ns) out.push_back({t, Source::kWheelSpeeds, i});
  }
  for (size_t i = 0; use_wheel && i < dataset.odometry.size(); ++i) {
    const int64_t t = dataset.odometry[i].t_ns;
    if (t > t0_ns) out.push_back({t, Source::kOdometry, i});
  }
  for (size_t i = 0; use_gnss && i < dataset.gnss.size(); ++i) {
    if (dataset.gnss[i].t_ns > t0_ns) out.push_back({dataset.gnss[i].t_ns, Source::kGnss, i});
  }
  const double sweep_period_s = SweepPeriodS(dataset);
  for (size_t i = first_sweep; keyframe_period_ns == 0 && i < dataset.lidar_sweeps.size(); ++i) {
    const int64_t t = dataset.lidar_sweeps[i].t_ns;
    out.push_back({t + SecondsToNs(sweep_period_s), Source::kSweep, i});
  }
  for (int64_t t = t0_ns + keyframe_period_ns;
       keyframe_period_ns > 0 && !dataset.imu.empty() && t <= dataset.imu.back().t_ns;
       t += keyframe_period_ns) {
    out.push_back({t, Source::kKeyframeTime, 0});
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const Arrival& a, const Arrival& b) { return a.t_ns < b.t_ns; });
  return out;
}

// When the estimate's steps are taken (Eq. W9): after the first update at or past the end of
// each of the first stretches - 1 of `stretches` equal spans of [begin_ns, end_ns] (the last
// checkpoint is the result's).
class CheckpointSchedule {
 public:
  CheckpointSchedule(int64_t begin_ns, int64_t end_ns, int stretches)
      : begin_ns_(begin_ns), span_ns_(end_ns - begin_ns), stretches_(stretches) {}

  // Whether an update at t_ns takes the next checkpoint (then the one after is next).
  bool Due(int64_t t_ns) {
    if (next_ >= stretches_ || t_ns < begin_ns_ + span_ns_ * next_ / stretches_) return false;
    ++next_;
    return true;
  }

 private:
  int64_t begin_ns_, span_ns_, stretches_;
  int64_t next_ = 1;
};

// Streams the arrivals into the estimator, the first sweeps from *initial_sweeps (moved),
// the others read from disk (one ahead when there is a second thread). Records the
// calibration after every update, and with its covariance in *checkpoints when
// CheckpointSchedule says (Eq. W9; *failed_checkpoints counts those whose covariance could not
// be computed); reports progress; throws when nothing was estimated.
void StreamArrivals(const io::Dataset& dataset, const io::Problem& problem,
                    const OnlineEstimationOptions& options, const std::vector<Arrival>& arrivals,
                    std::vector<lidar::LidarSweep>* initial_sweeps,
                    estimation::SlidingWindowEstimator* estimator, OnlineEstimationResult* result,
                    std::vector<estimation::CalibrationCheckpoint>* checkpoints,
                    int* failed_checkpoints) {
  const int64_t log_begin_ns = arrivals.empty() ? 0 : arrivals.front().t_ns;
  const int64_t log_end_ns = arrivals.empty() ? 0 : arrivals.back().t_ns;
  CheckpointSchedule schedule(log_begin_ns, log_end_ns, options.scatter_stretches);
  int64_t updates = 0;
  internal::SweepReader reader(dataset, problem.solver.num_threads > 1);
  for (const Arrival& a : arrivals) {
    switch (a.source) {
      case Source::kImu:
        estimator->AddImu(dataset.imu[a.index]);
        break;
      case Source::kWheel:
        estimator->AddWheel(dataset.wheel[a.index]);
        break;
      case Source::kWheelSpeeds:
        estimator->AddWheelSpeeds(dataset.wheel_speeds[a.index]);
        break;
      case Source::kOdometry:
        estimator->AddOdometry(dataset.odometry[a.index]);
        break;
      case Source::kGnss:
        estimator->AddGnss(dataset.gnss[a.index]);
        break;
      case Source::kSweep:
        estimator->AddSweep(a.index < initial_sweeps->size() ? std::move((*initial_sweeps)[a.index])
                                                             : reader.Take(a.index));
        break;
      case Source::kKeyframeTime:
        estimator->AddKeyframeAt(a.t_ns);
        break;
    }
    if (estimator->counters().updates == updates) continue;
    updates = estimator->counters().updates;
    result->calibration_over_time.push_back(
        {estimator->latest_state().t_ns, estimator->calibration()});
    if (schedule.Due(a.t_ns)) {
      try {
        checkpoints->push_back(
            {estimator->calibration(), estimator->ComputeCalibrationCovariance()});
      } catch (const Error&) {
        ++*failed_checkpoints;  // the test takes the others
      }
    }
    if (options.progress) {
      OnlineEstimationProgress progress;
      progress.log_fraction = log_end_ns > log_begin_ns
                                  ? static_cast<double>(a.t_ns - log_begin_ns) /
                                        static_cast<double>(log_end_ns - log_begin_ns)
                                  : 1.0;
      progress.updates = updates;
      progress.update_s = estimator->last_update_timing().total_s;
      progress.calibration = estimator->calibration();
      options.progress(progress);
    }
  }
  if (updates == 0) {
    throw Error("dataset " + dataset.directory + ": no " +
                (dataset.sensors.lidar && problem.sensors.lidar ? "sweep" : "keyframe time") +
                " after the initial state was covered by the IMU log; nothing was estimated");
  }
}

// The trajectories, states, counters and calibration of the estimator; returns the
// calibration covariance.
estimation::CalibrationCovariance CollectResult(
    const estimation::SlidingWindowOptions& window_options, bool use_lidar,
    estimation::SlidingWindowEstimator* estimator, OnlineEstimationResult* result) {
  for (const estimation::SlidingWindowState& x : estimator->Trajectory()) {
    result->trajectory.push_back(TrajectorySampleOf(x));
    result->states.push_back(x);
  }
  if (window_options.smoothing) {
    for (const estimation::SlidingWindowState& x : estimator->SmoothedTrajectory()) {
      result->smoothed_trajectory.push_back(TrajectorySampleOf(x));
    }
  }
  result->counters = estimator->counters();
  io::CalibrationFile& file = result->calibration;
  file.value = estimator->calibration();
  estimation::CalibrationCovariance covariance = estimator->ComputeCalibrationCovariance();
  file.solver["estimator"] = "sliding_window";
  file.solver["window_size"] = std::to_string(window_options.window_size);
  file.solver["updates"] = std::to_string(result->counters.updates);
  file.solver["marginalizations"] = std::to_string(result->counters.marginalizations);
  file.solver["dropped_late"] = std::to_string(result->counters.late);
  file.solver["dropped_late_gnss"] = std::to_string(result->counters.late_gnss);
  file.solver["skipped_without_imu"] = std::to_string(result->counters.without_imu);
  if (use_lidar) {
    file.residuals["lidar"]["rms_m"] = estimator->last_point_rms_m();
    file.residuals["lidar"]["points"] = estimator->last_associated_points();
  }
  if (result->counters.gnss_accepted > 0) {
    RecordGnssNoiseScale(estimator->gnss_std_scale(), &file);
    const estimation::GnssStdScale largest = estimator->largest_gnss_std_scale();
    file.residuals["gnss"]["largest_noise_scale_horizontal"] = largest.horizontal;
    file.residuals["gnss"]["largest_noise_scale_vertical"] = largest.vertical;
    file.residuals["gnss"]["fixes_scaled"] = static_cast<double>(result->counters.gnss_scaled);
  }
  return covariance;
}

// Eq. N2's warning when the window scaled fixes' std; empty when it did not. Per axis group
// whose fixes took a scale: the largest they took and the rows' scatter at the end of the
// stream, which may have fallen below the threshold since (stretches of poorer fixes).
std::string WindowGnssNoiseWarning(const estimation::SlidingWindowEstimator& estimator,
                                   const estimation::SlidingWindowOptions& window_options) {
  const estimation::SlidingWindowCounters& counters = estimator.counters();
  if (counters.gnss_scaled == 0) return "";
  const estimation::GnssNoiseFromResiduals noise = estimator.gnss_noise();
  const estimation::GnssStdScale largest = estimator.largest_gnss_std_scale();
  std::vector<std::string> groups;
  const auto group = [&](const char* name, double largest_scale,
                         const estimation::GnssAxisNoise& at_end) {
    if (largest_scale == 1.0) return;
    char text[240];
    std::snprintf(text, sizeof(text),
                  "the %s fixes' std scaled by up to %.2f, their rows scattering %.2f times it "
                  "over the %zu marginalized by the end",
                  name, largest_scale, at_end.robust_sigma, at_end.rows);
    groups.push_back(text);
  };
  group("horizontal", largest.horizontal, noise.horizontal);
  group("vertical", largest.vertical, noise.vertical);
  const std::string before =
      window_options.gnss_std_scale.IsOne() ? "as stated before" : "with the start's scale before";
  return "GNSS: " + std::to_string(counters.gnss_scaled) + " of the " +
         std::to_string(counters.gnss_accepted) +
         " fixes the window received took their std scaled by the scatter of the rows it had "
         "marginalized (robust sigma of the whitened rows, Eq. N2; " +
         before + " " + std::to_string(estimation::kMinGnssNoiseRows) +
         " rows of an axis group, and only while it was at least " +
         FormatShort(estimation::kMinGnssNoiseScale) +
         " times the stated std): " + Join(groups, "; ") + ". " + kGnssScatterCauses +
         "; a scatter that changes along the stream points to stretches of poorer fixes";
}

}  // namespace

namespace {

// The result's final calibration and every sample of calibration_over_time.
std::vector<sensors::Calibration*> CalibrationsOf(OnlineEstimationResult* result) {
  std::vector<sensors::Calibration*> out{&result->calibration.value};
  for (CalibrationSample& sample : result->calibration_over_time) {
    out.push_back(&sample.calibration);
  }
  return out;
}

}  // namespace

OnlineEstimationResult EstimateDatasetOnline(const io::Dataset& input,
                                             const io::Problem& problem_in,
                                             const OnlineEstimationOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  io::ValidateProblemForDataset(problem_in, input);
  CheckOnlineInputs(input, problem_in, options);
  std::vector<std::string> start_warnings;
  std::optional<io::Dataset> with_measured_noise;
  const io::Dataset& log = WithImuNoiseFromData(input, &with_measured_noise, &start_warnings);
  // Without the LiDAR the window reads the wheels and GNSS on the IMU clock, its mount from
  // the data.
  io::Problem problem = problem_in;
  sensors::Calibration applied = log.sensors.nominal_calibration;
  const io::Dataset shifted =
      problem.sensors.lidar ? io::Dataset() : OnImuClock(log, &problem, &applied, &start_warnings);
  const io::Dataset& dataset = problem.sensors.lidar ? log : shifted;
  const bool use_lidar = problem.sensors.lidar;
  const bool use_wheel = problem.sensors.wheel && dataset.wheel_sample_count() > 0;
  const bool use_gnss = problem.sensors.gnss && !dataset.gnss.empty();
  estimation::SlidingWindowOptions window_options =
      WindowOptions(dataset, problem, use_wheel, use_gnss, options);
  const TimingLimits timing = DeriveTimingLimits(dataset, problem, use_wheel, use_gnss);
  OnlineEstimationResult result;

  // 1. The initial state. With the LiDAR: the initializer on the first seconds of the log,
  //    whose sweeps are kept for the streaming, which would otherwise read them from disk
  //    again. Without: the GNSS-inertial keyframes over those seconds, and a keyframe period.
  InitialSeconds first;
  WindowStart window_start;
  int64_t keyframe_period_ns = 0;
  if (use_lidar) {
    first = InitializeOnFirstSeconds(dataset, problem, options, use_gnss, &start_warnings);
    window_start = StartWindow(dataset, problem, options, timing, first.init, use_wheel, use_gnss,
                               &window_options, &start_warnings);
    result.seconds_initialization = SecondsSince(start);
  } else {
    keyframe_period_ns = KeyframePeriodWithoutLidar(dataset, options);
    window_start.calibration = dataset.sensors.nominal_calibration;
    window_start.keyframe = StartWithoutLidar(dataset, problem, options, timing, keyframe_period_ns,
                                              use_wheel, &window_options, &start_warnings);
    result.seconds_initialization = SecondsSince(start);
  }
  result.initial = window_start.calibration;
  result.keyframe_period_s = NsToSeconds(keyframe_period_ns);
  window_options.wheel_rows.planar_rotation_sigma_rad_s = PlanarRotationSigma(
      dataset, problem, use_wheel, use_lidar ? SweepPeriodS(dataset) : result.keyframe_period_s,
      window_start.calibration.q_I_V, window_options.wheel_rows);
  estimation::SlidingWindowEstimator estimator(window_options, window_start.calibration,
                                               window_start.keyframe);

  // 2. Every datum after the initial state in arrival order.
  const int64_t t0 = window_start.keyframe.t_ns;
  RequireSamplesAfter(dataset, use_wheel, use_gnss, t0);
  const size_t first_sweep = use_lidar ? first.start_sweep + 1 : 0;
  const std::vector<Arrival> arrivals =
      ArrivalOrder(dataset, use_wheel, use_gnss, t0, first_sweep, keyframe_period_ns);
  std::vector<estimation::CalibrationCheckpoint> checkpoints;
  int failed_checkpoints = 0;
  StreamArrivals(dataset, problem, options, arrivals, &first.sweeps, &estimator, &result,
                 &checkpoints, &failed_checkpoints);
  RequireStreamedSamples(dataset, use_wheel, use_gnss, estimator.counters());

  // 3. The result, its sigmas widened where the estimate's steps scatter (Eq. W9).
  checkpoints.push_back(
      {estimator.calibration(), CollectResult(window_options, use_lidar, &estimator, &result)});
  std::vector<std::string> held_warnings;
  const std::string dropout =
      ImuDropoutWarning(dataset.imu, estimator.counters().without_imu, "the window");
  if (!dropout.empty()) held_warnings.push_back(dropout);
  if (const int64_t late = estimator.counters().late_gnss; late > 0) {
    held_warnings.push_back(
        "the window: " + std::to_string(late) + " of " +
        std::to_string(late + estimator.counters().gnss_accepted) +
        " GNSS fixes came at or before the newest keyframe, whose interval was already solved, "
        "and were left out (calibration.yaml: solver.dropped_late_gnss); the offline "
        "calibration uses every fix");
  }
  const std::string gnss_noise = WindowGnssNoiseWarning(estimator, window_options);
  if (!gnss_noise.empty()) held_warnings.push_back(gnss_noise);
  if (failed_checkpoints > 0) {
    held_warnings.push_back("the window's covariance could not be computed at " +
                            std::to_string(failed_checkpoints) + " of " +
                            std::to_string(options.scatter_stretches - 1) +
                            " checkpoints of the stream; its steps were judged at the others "
                            "(Eq. W9)");
  }
  const estimation::CalibrationCovariance& solved = checkpoints.back().covariance;
  const estimation::CalibrationCovariance widened =
      WidenedForSteps(window_options, checkpoints, options.scatter_significance,
                      &result.calibration, &held_warnings);
  FillWindowUncertainty(widened, &result.calibration.uncertainty);
  WarnOfFixedDirectionsTheStreamMoves(dataset, problem, use_wheel, use_gnss, &estimator,
                                      &held_warnings);
  if (HoldWhatTheStreamLeft(dataset, problem, window_options, use_wheel, use_gnss, solved, widened,
                            &result.calibration.value, &result.calibration.uncertainty,
                            &held_warnings) &&
      window_options.smoothing) {
    // The smoothed trajectory at the calibration that is reported.
    result.smoothed_trajectory.clear();
    for (const estimation::SlidingWindowState& x :
         estimator.SmoothedTrajectory(result.calibration.value)) {
      result.smoothed_trajectory.push_back(TrajectorySampleOf(x));
    }
  }
  if (!use_lidar) {
    // The stream ran on stamps moved onto the IMU clock (OnImuClock): the clocks it used are
    // the applied offsets, in the result and in every sample of the stream's calibration.
    result.calibration.solver["keyframe_period_s"] = FormatSeconds(keyframe_period_ns);
    for (sensors::Calibration* c : CalibrationsOf(&result)) {
      c->time_offset_wheel_imu_s = applied.time_offset_wheel_imu_s;
      c->time_offset_gnss_imu_s = applied.time_offset_gnss_imu_s;
    }
  }
  result.warnings = start_warnings;
  result.warnings.insert(result.warnings.end(), held_warnings.begin(), held_warnings.end());
  result.seconds_total = SecondsSince(start);
  return result;
}

}  // namespace pipeline
}  // namespace autocal
