#include "autocal/pipeline/online_estimation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <optional>
#include <sstream>
#include <tuple>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"
#include "autocal/common/time.h"
#include "autocal/estimation/gnss_inertial_keyframes.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/output_files.h"
#include "autocal/io/tum_trajectory.h"
#include "calibration_steps.h"
#include "sweep_reader.h"

namespace autocal {
namespace pipeline {

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

// The window's priors are one sigma per block: the problem's in prior mode, else the sigma
// the dataset states for its nominal value, else the window's default; a per-axis sigma takes
// its widest axis (as the offline calibration, src/pipeline/problem_blocks.cc, minus the axes).
double PriorSigma(const io::VectorBlockSetting& s, const std::optional<Eigen::Vector3d>& stated,
                  double fallback) {
  if (s.mode == io::BlockMode::kPrior) return s.prior_sigma.maxCoeff();
  return stated ? stated->maxCoeff() : fallback;
}
double PriorSigma(const io::ScalarBlockSetting& s, const std::optional<double>& stated,
                  double fallback) {
  if (s.mode == io::BlockMode::kPrior) return s.prior_sigma;
  return stated ? *stated : fallback;
}

// A keyframe as a trajectory sample (pose and velocity).
io::TrajectorySample TrajectorySampleOf(const estimation::SlidingWindowState& x) {
  io::TrajectorySample s;
  s.t_ns = x.t_ns;
  s.T_W_I = geometry::Pose3d(x.q_W_I, x.p_W_I);
  s.v_W_I = x.v_W_I;
  return s;
}

// The window options of a problem: what it estimates, its priors, losses and solver.
estimation::SlidingWindowOptions WindowOptions(const io::Dataset& dataset,
                                               const io::Problem& problem, bool use_wheel,
                                               bool use_gnss,
                                               const OnlineEstimationOptions& options) {
  const io::ProblemCalibration& b = problem.calibration;
  if (b.wheel_radius_shared) {
    throw Error("problem " + problem.path + ": wheel_radius_shared is not supported by the "
                "online estimator (it estimates both radii)");
  }
  if (use_wheel &&
      Estimated(b.wheel_radius_left_m.mode) != Estimated(b.wheel_radius_right_m.mode)) {
    throw Error("problem " + problem.path + ": the online estimator estimates both wheel radii "
                "or neither; the problem fixes only one");
  }
  estimation::SlidingWindowOptions w = options.window;
  w.imu = dataset.sensors.imu;
  if (dataset.sensors.wheel) w.wheel = *dataset.sensors.wheel;
  w.loss = problem.loss;
  w.window_size = problem.window_size;
  w.solver.max_iterations = problem.solver.max_iterations;
  w.num_threads = problem.solver.num_threads;
  w.pairing.max_residuals_per_sweep = problem.lidar.max_points_per_sweep;
  w.pairing.residual_voxel_m = problem.lidar.voxel_m;
  w.pairing.residual_max_range_m = problem.window_max_range_m;
  w.initial_state_sigmas = options.initial_state_sigmas;
  // The rear axle's lateral and vertical speed rows, weighted for their correlated model error
  // (Eq. K6, as in the offline calibration). Without them the wheel speeds see the vehicle
  // frame's pitch and yaw only through the cosine that scales the speed along x_V, as the radii
  // do: on the 60 s urban log the window drifted along that valley to 5.7 deg and -0.47 %
  // (docs/sliding_window.md).
  w.wheel_rows.non_holonomic = use_wheel;

  estimation::SlidingWindowEstimatedBlocks& e = w.estimate;
  e.extrinsic_rotation = Estimated(b.T_I_L.rotation.mode);
  e.extrinsic_translation = Estimated(b.T_I_L.translation.mode);
  e.time_offset = Estimated(b.time_offset_lidar_imu_s.mode);
  e.wheel_radii = use_wheel && Estimated(b.wheel_radius_left_m.mode);
  e.track_width = use_wheel && Estimated(b.track_width_m.mode);
  e.vehicle_frame =
      use_wheel && (Estimated(b.T_I_V.rotation.mode) || Estimated(b.T_I_V.translation.mode));
  e.gnss_lever_arm = use_gnss && Estimated(b.p_I_A_m.mode);

  // The priors are the nominal calibration's, as in the offline calibration: the initializer's
  // values only start the window.
  estimation::SlidingWindowCalibrationPrior& p = w.calibration_prior;
  p.mean = dataset.sensors.nominal_calibration;
  const io::CalibrationUncertainty& u = dataset.sensors.nominal_uncertainty;
  p.extrinsic_rotation_deg =
      PriorSigma(b.T_I_L.rotation, u.T_I_L.sigma_rot_deg, p.extrinsic_rotation_deg);
  p.extrinsic_translation_m =
      PriorSigma(b.T_I_L.translation, u.T_I_L.sigma_p_m, p.extrinsic_translation_m);
  p.time_offset_s =
      PriorSigma(b.time_offset_lidar_imu_s, u.time_offset_lidar_imu_s.sigma, p.time_offset_s);
  p.wheel_radius_m = std::max(
      PriorSigma(b.wheel_radius_left_m, u.wheel_radius_left_m.sigma, p.wheel_radius_m),
      PriorSigma(b.wheel_radius_right_m, u.wheel_radius_right_m.sigma, p.wheel_radius_m));
  p.track_width_m = PriorSigma(b.track_width_m, u.track_width_m.sigma, p.track_width_m);
  p.vehicle_rotation_deg =
      PriorSigma(b.T_I_V.rotation, u.T_I_V.sigma_rot_deg, p.vehicle_rotation_deg);
  p.vehicle_translation_m =
      PriorSigma(b.T_I_V.translation, u.T_I_V.sigma_p_m, p.vehicle_translation_m);
  p.gnss_lever_arm_m = PriorSigma(b.p_I_A_m, u.p_I_A_m.sigma, p.gnss_lever_arm_m);
  return w;
}

// Sigmas of the estimated blocks from the window's covariance, into the calibration file.
void FillUncertainty(const estimation::CalibrationCovariance& covariance,
                     io::CalibrationUncertainty* u) {
  for (size_t b = 0; b < covariance.names.size(); ++b) {
    const int i = covariance.offsets[b];
    const std::string& name = covariance.names[b];
    const auto sigma = [&](int k) {
      return std::sqrt(std::max(0.0, covariance.covariance(i + k, i + k)));
    };
    const auto sigma3 = [&]() { return Eigen::Vector3d(sigma(0), sigma(1), sigma(2)); };
    if (name == "q_I_L") u->T_I_L.sigma_rot_deg = sigma3() * kRadToDeg;
    if (name == "p_I_L") u->T_I_L.sigma_p_m = sigma3();
    if (name == "q_I_V") u->T_I_V.sigma_rot_deg = sigma3() * kRadToDeg;
    if (name == "p_I_V") u->T_I_V.sigma_p_m = sigma3();
    if (name == "p_I_A") u->p_I_A_m.sigma = sigma3();
    if (name == "time_offset_lidar_imu_s") u->time_offset_lidar_imu_s.sigma = sigma(0);
    if (name == "wheel_radius_left_m") u->wheel_radius_left_m.sigma = sigma(0);
    if (name == "wheel_radius_right_m") u->wheel_radius_right_m.sigma = sigma(0);
    if (name == "track_width_m") u->track_width_m.sigma = sigma(0);
  }
}

// With GNSS, the start the window is given (docs/sliding_window.md, "Streaming a dataset",
// Eq. SW8). The initializer's IMU orientations are its LiDAR odometry's turned by its q_I_L,
// whose rotation about the vertical planar driving hardly determines (1.0 deg off on the
// 60 s urban log): every aligned keyframe's yaw was off by 1.4 deg, and the window's first
// keyframes kept that. The GNSS-inertial solve over the same keyframes (IMU, fixes, wheels)
// gives each IMU orientation from gravity and the track's accelerations instead (0.17 deg at
// the start of that log, 0.05 deg later). Returns that solve's first keyframe and, in *q_I_L,
// the extrinsic turned about the IMU's vertical by the median of
//   phi_k = u_k . Log(R_W_I,gnss_k^T R_W_I,aligned_k),  u_k = R_W_I,gnss_k^T z_W,
// so that the LiDAR keeps the orientation its odometry gave it: R_W_L = R_W_I R_I_L with
// R_I_L <- Exp(phi u) R_I_L, where the aligned keyframes' R_W_I = R_W_L R_I_L^T.
estimation::Keyframe StartFromGnssAndImu(const io::Dataset& dataset,
                                         const sensors::WheelSamples& wheel,
                                         const sensors::EnuConverter& enu,
                                         const std::vector<estimation::Keyframe>& aligned,
                                         bool estimate_q_I_L,
                                         const sensors::Calibration& calibration,
                                         Eigen::Quaterniond* q_I_L) {
  std::vector<estimation::Keyframe> refined = aligned;
  estimation::GnssInertialKeyframesOptions options;
  options.imu_noise = dataset.sensors.imu.noise;
  options.gravity_m_s2 = dataset.sensors.imu.gravity_m_s2;
  estimation::KeyframesFromGnssAndImu(&refined, dataset.imu, wheel, dataset.gnss, enu,
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
    const Eigen::Quaterniond turn(
        Eigen::AngleAxisd(phi[phi.size() / 2], up_I.normalized()));
    *q_I_L = (turn * calibration.q_I_L).normalized();
  }
  return refined.front();
}

void WriteStatesCsv(const std::string& path,
                    const std::vector<estimation::SlidingWindowState>& states) {
  std::ostringstream csv;
  csv << "t_s,p_W_I_x_m,p_W_I_y_m,p_W_I_z_m,q_W_I_x,q_W_I_y,q_W_I_z,q_W_I_w,"
         "v_W_I_x_m_s,v_W_I_y_m_s,v_W_I_z_m_s,b_g_x_rad_s,b_g_y_rad_s,b_g_z_rad_s,"
         "b_a_x_m_s2,b_a_y_m_s2,b_a_z_m_s2\n";
  csv << std::setprecision(12);
  for (const estimation::SlidingWindowState& x : states) {
    csv << FormatSeconds(x.t_ns);
    const auto row = [&csv](const auto& v) {
      for (int i = 0; i < v.size(); ++i) csv << ',' << v[i];
    };
    row(x.p_W_I);
    row(x.q_W_I.coeffs());
    row(x.v_W_I);
    row(x.b_g);
    row(x.b_a);
    csv << '\n';
  }
  io::WriteFileAtomically(path, csv.str());
}

}  // namespace

OnlineEstimationResult EstimateDatasetOnline(const io::Dataset& dataset,
                                             const io::Problem& problem,
                                             const OnlineEstimationOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  io::ValidateProblemForDataset(problem, dataset);
  if (!problem.sensors.lidar) {
    throw Error("problem " + problem.path + ": the online estimator needs the LiDAR (its "
                "keyframes are the sweeps)");
  }
  if (!(options.initialization_duration_s > 0.0) ||
      !(options.initial_position_sigma_with_gnss_m > 0.0) ||
      !(options.initial_accel_bias_sigma_with_gnss_m_s2 > 0.0) ||
      options.initializer_sweep_stride < 1) {
    throw Error("OnlineEstimationOptions: initialization_duration_s, "
                "initial_position_sigma_with_gnss_m, initial_accel_bias_sigma_with_gnss_m_s2 "
                "and initializer_sweep_stride must be positive");
  }
  const bool use_wheel = problem.sensors.wheel && !dataset.wheel.empty();
  const bool use_gnss = problem.sensors.gnss && !dataset.gnss.empty();
  estimation::SlidingWindowOptions window_options =
      WindowOptions(dataset, problem, use_wheel, use_gnss, options);
  OnlineEstimationResult result;

  // 1. The initial state: the initializer on the first seconds of the log. Its sweeps are
  //    kept for the streaming, which would otherwise read them from disk again.
  const int64_t init_end_ns = dataset.lidar_sweeps.front().t_ns +
                              SecondsToNs(options.initialization_duration_s);
  size_t num_init_sweeps = 0;
  while (num_init_sweeps < dataset.lidar_sweeps.size() &&
         dataset.lidar_sweeps[num_init_sweeps].t_ns < init_end_ns) {
    ++num_init_sweeps;
  }
  std::vector<lidar::LidarSweep> sweeps(num_init_sweeps);
  ParallelFor(0, static_cast<int64_t>(num_init_sweeps), problem.solver.num_threads,
              [&](int64_t begin, int64_t end, int) {
                for (int64_t i = begin; i < end; ++i) {
                  sweeps[static_cast<size_t>(i)] = dataset.LoadSweep(static_cast<size_t>(i));
                }
              });
  estimation::CalibrationInitializerOptions init_options = options.initializer;
  init_options.imu_noise = dataset.sensors.imu.noise;
  init_options.p_I_L_prior = dataset.sensors.nominal_calibration.p_I_L;
  init_options.keyframe_lead_s = options.window.keyframe_lead_s;
  // Every initializer_sweep_stride-th sweep is lent to the initializer (moved there and back).
  const size_t stride = static_cast<size_t>(options.initializer_sweep_stride);
  std::vector<lidar::LidarSweep> init_sweeps;
  for (size_t i = 0; i < sweeps.size(); i += stride) init_sweeps.push_back(std::move(sweeps[i]));
  const estimation::CalibrationInitialization init =
      estimation::InitializeLidarImu(dataset.imu, init_sweeps, init_options);
  for (size_t k = 0; k < init_sweeps.size(); ++k) sweeps[k * stride] = std::move(init_sweeps[k]);
  result.seconds_initialization =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!init.ok || init.keyframes.empty()) {
    throw Error("dataset " + dataset.directory + ": the initializer could not start the window "
                "from the first " + std::to_string(options.initialization_duration_s) +
                " s: " + Join(init.problems, "; "));
  }
  sensors::Calibration calibration = dataset.sensors.nominal_calibration;
  const io::ProblemCalibration& blocks = problem.calibration;
  if (Estimated(blocks.T_I_L.rotation.mode)) calibration.q_I_L = init.q_I_L;
  if (Estimated(blocks.T_I_L.translation.mode)) calibration.p_I_L = init.p_I_L;
  if (Estimated(blocks.time_offset_lidar_imu_s.mode)) {
    calibration.time_offset_lidar_imu_s = init.time_offset_lidar_imu_s;
  }
  std::vector<estimation::Keyframe> keyframes = init.keyframes;
  if (use_gnss) {
    // W is the ENU frame at the first fix: the initializer's gravity-aligned keyframes are
    // moved there by the 4-DoF alignment.
    const sensors::EnuConverter enu = sensors::EnuConverter::AtFirstFix(dataset.gnss);
    estimation::AlignKeyframesToGnss(&keyframes, dataset.gnss, enu, calibration.p_I_A);
    keyframes.front() = StartFromGnssAndImu(
        dataset, use_wheel ? dataset.wheel : sensors::WheelSamples(), enu, keyframes,
        Estimated(blocks.T_I_L.rotation.mode), calibration, &calibration.q_I_L);
    window_options.enu_origin_lla = Eigen::Vector3d(enu.lat0_deg(), enu.lon0_deg(), enu.alt0_m());
    window_options.initial_state_sigmas.position_m = options.initial_position_sigma_with_gnss_m;
    window_options.initial_state_sigmas.accel_bias_m_s2 =
        options.initial_accel_bias_sigma_with_gnss_m_s2;
  }
  // The initializer's keyframes use its time offset; the window's keyframe time rule
  // (KeyframeTimeOf) uses the calibration's, which is the same value or the nominal one.
  const estimation::Keyframe initial = keyframes.front();
  result.initial = calibration;
  estimation::SlidingWindowEstimator estimator(window_options, calibration, initial);

  // 2. Every datum after the initial state in arrival order: a sweep arrives when its last
  //    point is measured, IMU samples from the last one at or before the initial state on.
  enum Kind { kImu, kWheel, kGnss, kSweep };
  std::vector<std::tuple<int64_t, int, size_t>> events;
  const int64_t t0 = initial.t_ns;
  RequireSamplesAfter(dataset, use_wheel, use_gnss, t0);
  for (size_t i = 0; i < dataset.imu.size(); ++i) {
    const bool needed = dataset.imu[i].t_ns > t0 ||
                        (i + 1 < dataset.imu.size() && dataset.imu[i + 1].t_ns > t0);
    if (needed) events.emplace_back(dataset.imu[i].t_ns, kImu, i);
  }
  if (use_wheel) {
    for (size_t i = 0; i < dataset.wheel.size(); ++i) {
      if (dataset.wheel[i].t_ns > t0) events.emplace_back(dataset.wheel[i].t_ns, kWheel, i);
    }
  }
  if (use_gnss) {
    for (size_t i = 0; i < dataset.gnss.size(); ++i) {
      if (dataset.gnss[i].t_ns > t0) events.emplace_back(dataset.gnss[i].t_ns, kGnss, i);
    }
  }
  // A sweep's keyframe precedes its stamp by less than keyframe_lead_s plus the offset; one
  // whose keyframe would precede the initial state belongs to no interval. Its arrival time
  // is its stamp plus the sweep period (the points' times are known once it is loaded).
  const double sweep_period_s =
      dataset.sensors.lidar ? 1.0 / dataset.sensors.lidar->rate_hz : 0.1;
  for (size_t i = 0; i < dataset.lidar_sweeps.size(); ++i) {
    const int64_t t = dataset.lidar_sweeps[i].t_ns;
    const double lead_s = window_options.keyframe_lead_s;
    if (t + SecondsToNs(calibration.time_offset_lidar_imu_s - lead_s) <= t0) {
      continue;
    }
    events.emplace_back(t + SecondsToNs(sweep_period_s), kSweep, i);
  }
  std::stable_sort(events.begin(), events.end(), [](const auto& a, const auto& b) {
    return std::get<0>(a) < std::get<0>(b);
  });

  const int64_t log_begin_ns = events.empty() ? t0 : std::get<0>(events.front());
  const int64_t log_end_ns = events.empty() ? t0 : std::get<0>(events.back());
  int64_t updates = 0;
  // The streamed sweeps are read one ahead when there is a second thread.
  internal::SweepReader reader(dataset, problem.solver.num_threads > 1);
  for (const auto& [t, kind, i] : events) {
    switch (kind) {
      case kImu: estimator.AddImu(dataset.imu[i]); break;
      case kWheel: estimator.AddWheel(dataset.wheel[i]); break;
      case kGnss: estimator.AddGnss(dataset.gnss[i]); break;
      default:
        if (i < sweeps.size()) {
          estimator.AddSweep(std::move(sweeps[i]));
        } else {
          estimator.AddSweep(reader.Take(i));
        }
        break;
    }
    if (estimator.counters().updates == updates) continue;
    updates = estimator.counters().updates;
    result.calibration_over_time.push_back(
        {estimator.latest_state().t_ns, estimator.calibration()});
    if (options.progress) {
      OnlineEstimationProgress progress;
      progress.log_fraction = log_end_ns > log_begin_ns
                                  ? static_cast<double>(t - log_begin_ns) /
                                        static_cast<double>(log_end_ns - log_begin_ns)
                                  : 1.0;
      progress.updates = updates;
      progress.update_s = estimator.last_update_timing().total_s;
      progress.calibration = estimator.calibration();
      options.progress(progress);
    }
  }
  if (updates == 0) {
    throw Error("dataset " + dataset.directory + ": no sweep after the initial state was "
                "covered by the IMU log; nothing was estimated");
  }
  RequireStreamedSamples(dataset, use_wheel, use_gnss, estimator.counters());

  // 3. The result.
  for (const estimation::SlidingWindowState& x : estimator.Trajectory()) {
    result.trajectory.push_back(TrajectorySampleOf(x));
    result.states.push_back(x);
  }
  if (window_options.smoothing) {
    for (const estimation::SlidingWindowState& x : estimator.SmoothedTrajectory()) {
      result.smoothed_trajectory.push_back(TrajectorySampleOf(x));
    }
  }
  result.counters = estimator.counters();
  result.calibration.value = estimator.calibration();
  FillUncertainty(estimator.ComputeCalibrationCovariance(), &result.calibration.uncertainty);
  result.calibration.solver["estimator"] = "sliding_window";
  result.calibration.solver["window_size"] = std::to_string(window_options.window_size);
  result.calibration.solver["updates"] = std::to_string(result.counters.updates);
  result.calibration.solver["marginalizations"] = std::to_string(result.counters.marginalizations);
  result.calibration.solver["dropped_late"] = std::to_string(result.counters.late);
  result.calibration.residuals["lidar"]["rms_m"] = estimator.last_point_rms_m();
  result.calibration.residuals["lidar"]["points"] = estimator.last_associated_points();
  result.seconds_total =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

void WriteOnlineEstimationResult(const std::string& directory,
                                 const OnlineEstimationResult& result) {
  io::StagedDirectory out(directory, io::OutputKind::kResult);
  io::WriteCalibrationYaml(out.File("calibration.yaml"), result.calibration);
  io::WriteTumTrajectory(out.File("trajectory.tum"), result.trajectory);
  if (!result.smoothed_trajectory.empty()) {
    io::WriteTumTrajectory(out.File("trajectory_smoothed.tum"), result.smoothed_trajectory);
  }
  WriteStatesCsv(out.File("states.csv"), result.states);
  std::ostringstream csv;
  csv << "t_s,q_I_L_x,q_I_L_y,q_I_L_z,q_I_L_w,p_I_L_x_m,p_I_L_y_m,p_I_L_z_m,"
         "time_offset_lidar_imu_s,wheel_radius_left_m,wheel_radius_right_m,track_width_m,"
         "p_I_A_x_m,p_I_A_y_m,p_I_A_z_m\n";
  csv << std::setprecision(12);
  for (const CalibrationSample& s : result.calibration_over_time) {
    const sensors::Calibration& c = s.calibration;
    csv << FormatSeconds(s.t_ns);
    csv << ',' << c.q_I_L.x() << ',' << c.q_I_L.y() << ',' << c.q_I_L.z() << ',' << c.q_I_L.w()
        << ',' << c.p_I_L.x() << ',' << c.p_I_L.y() << ',' << c.p_I_L.z() << ','
        << c.time_offset_lidar_imu_s << ',' << c.wheel_radius_left_m << ','
        << c.wheel_radius_right_m << ',' << c.track_width_m << ',' << c.p_I_A.x() << ','
        << c.p_I_A.y() << ',' << c.p_I_A.z() << '\n';
  }
  io::WriteFileAtomically(out.File("calibration_over_time.csv"), csv.str());
  std::ostringstream timings;
  timings << "# autocal_estimate wall-clock seconds (differ from run to run)\n"
          << "seconds_total: " << result.seconds_total << "\n"
          << "seconds_initialization: " << result.seconds_initialization << "\n";
  io::WriteFileAtomically(out.File("timings.yaml"), timings.str());
  out.Commit();
}

}  // namespace pipeline
}  // namespace autocal
