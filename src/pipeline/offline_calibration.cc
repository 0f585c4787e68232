#include "autocal/pipeline/offline_calibration.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <optional>
#include <sstream>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/parallel_for.h"
#include "autocal/estimation/gnss_inertial_keyframes.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/tum_trajectory.h"
#include "autocal/pipeline/report_html.h"
#include "calibration_blocks.h"

namespace autocal {
namespace pipeline {

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

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

// The batch solver's settings from the problem and the dataset.
estimation::LidarInertialBatchOptions BatchOptions(const io::Dataset& dataset,
                                                   const io::Problem& problem) {
  estimation::LidarInertialBatchOptions batch;
  batch.imu_noise = dataset.sensors.imu.noise;
  batch.gravity_m_s2 = dataset.sensors.imu.gravity_m_s2;
  batch.max_residuals_per_sweep = problem.lidar.max_points_per_sweep;
  batch.residual_voxel_m = problem.lidar.voxel_m;
  batch.point_loss = problem.loss.lidar;
  batch.outer_iterations = problem.solver.outer_iterations;
  batch.solver_iterations = problem.solver.max_iterations;
  batch.num_threads = problem.solver.num_threads;
  batch.estimate_extrinsic_rotation = Estimated(problem.calibration.T_I_L.rotation.mode);
  batch.estimate_extrinsic_translation = Estimated(problem.calibration.T_I_L.translation.mode);
  batch.estimate_time_offset = Estimated(problem.calibration.time_offset_lidar_imu_s.mode);
  return batch;
}

std::string Join(const std::vector<std::string>& parts, const std::string& separator) {
  std::string out;
  for (size_t i = 0; i < parts.size(); ++i) out += (i == 0 ? "" : separator) + parts[i];
  return out;
}


// Prior sigma per direction: the problem's for a block in prior mode, else the dataset's
// nominal uncertainty when it states one, else the default.
Eigen::VectorXd PriorSigma(io::BlockMode mode, const Eigen::VectorXd& problem_sigma,
                           const std::optional<Eigen::VectorXd>& nominal_sigma,
                           const Eigen::VectorXd& fallback) {
  if (mode == io::BlockMode::kPrior) return problem_sigma;
  if (nominal_sigma) return *nominal_sigma;
  return fallback;
}

std::optional<Eigen::VectorXd> Optional(const std::optional<Eigen::Vector3d>& v, double scale = 1.0) {
  if (!v) return std::nullopt;
  return Eigen::VectorXd(*v * scale);
}

std::optional<Eigen::VectorXd> Optional(const std::optional<double>& v) {
  if (!v) return std::nullopt;
  return Eigen::VectorXd::Constant(1, *v);
}

// The blocks the solve estimates, with their priors and observability limits.
std::vector<CalibrationBlock> EstimatedBlocks(const io::Problem& problem,
                                              const io::SensorsConfig& sensors,
                                              const OfflineCalibrationOptions& o, bool use_wheel,
                                              bool use_gnss, sensors::Calibration* c) {
  const io::ProblemCalibration& p = problem.calibration;
  const sensors::Calibration& nominal = sensors.nominal_calibration;
  const io::CalibrationUncertainty& u = sensors.nominal_uncertainty;
  const double deg = 1.0 / kRadToDeg;
  std::vector<CalibrationBlock> blocks;
  const auto push = [&](CalibrationBlock b) {
    b.max_posterior_to_prior_sigma = o.max_posterior_to_prior_sigma;
    blocks.push_back(std::move(b));
  };
  auto rotation = [&](const std::string& name, const io::VectorBlockSetting& setting,
                      const std::optional<Eigen::Vector3d>& nominal_sigma_deg,
                      const Eigen::Quaterniond& q0, double* data, double max_sigma_deg,
                      std::vector<std::string> directions) {
    CalibrationBlock b;
    b.name = name;
    b.data = data;
    b.size = 3;
    b.rotation = true;
    b.prior = q0.coeffs();
    b.prior_sigma = PriorSigma(setting.mode, setting.prior_sigma * deg,
                               Optional(nominal_sigma_deg, deg),
                               Eigen::VectorXd::Constant(3, o.default_rotation_prior_sigma_deg * deg));
    b.max_observable_sigma = max_sigma_deg * deg;
    b.direction_names = std::move(directions);
    b.display_scale = kRadToDeg;
    b.display_unit = "deg";
    push(b);
  };
  auto vector = [&](const std::string& name, const io::VectorBlockSetting& setting,
                    const std::optional<Eigen::Vector3d>& nominal_sigma,
                    const Eigen::Vector3d& x0, double* data, double limit,
                    std::vector<std::string> directions) {
    CalibrationBlock b;
    b.name = name;
    b.data = data;
    b.size = 3;
    b.prior = x0;
    b.prior_sigma = PriorSigma(setting.mode, setting.prior_sigma, Optional(nominal_sigma),
                               Eigen::VectorXd::Constant(3, o.default_translation_prior_sigma_m));
    b.max_observable_sigma = limit;
    b.direction_names = std::move(directions);
    b.display_scale = 100.0;
    b.display_unit = "cm";
    push(b);
  };
  auto scalar = [&](const std::string& name, const io::ScalarBlockSetting& setting,
                    const std::optional<double>& nominal_sigma, double x0, double* data,
                    double fallback_sigma, double limit, double display_scale,
                    const std::string& unit) {
    CalibrationBlock b;
    b.name = name;
    b.data = data;
    b.size = 1;
    b.prior = Eigen::VectorXd::Constant(1, x0);
    b.prior_sigma = PriorSigma(setting.mode, Eigen::VectorXd::Constant(1, setting.prior_sigma),
                               Optional(nominal_sigma), Eigen::VectorXd::Constant(1, fallback_sigma));
    b.max_observable_sigma = limit;
    b.direction_names = {name};
    b.display_scale = display_scale;
    b.display_unit = unit;
    push(b);
  };
  if (Estimated(p.T_I_L.rotation.mode)) {
    rotation("T_I_L rotation", p.T_I_L.rotation, u.T_I_L.sigma_rot_deg, nominal.q_I_L,
             c->q_I_L.coeffs().data(), o.max_observable_rotation_sigma_deg,
             {"LiDAR rotation about the IMU x axis (roll)", "LiDAR rotation about the IMU y axis (pitch)",
              "LiDAR rotation about the IMU z axis (yaw)"});
  }
  if (Estimated(p.T_I_L.translation.mode)) {
    vector("T_I_L translation", p.T_I_L.translation, u.T_I_L.sigma_p_m, nominal.p_I_L,
           c->p_I_L.data(), o.max_observable_translation_sigma_m,
           {"LiDAR x translation (IMU frame)", "LiDAR y translation (IMU frame)",
            "LiDAR z translation (IMU frame; planar driving rotates about it only)"});
  }
  if (Estimated(p.time_offset_lidar_imu_s.mode)) {
    scalar("LiDAR-IMU time offset", p.time_offset_lidar_imu_s, u.time_offset_lidar_imu_s.sigma,
           nominal.time_offset_lidar_imu_s, &c->time_offset_lidar_imu_s,
           o.default_time_offset_prior_sigma_s, o.max_observable_time_offset_sigma_s, 1e3, "ms");
  }
  if (use_wheel) {
    const char* left = p.wheel_radius_shared ? "rear wheel radius (both wheels)" : "left rear wheel radius";
    if (Estimated(p.wheel_radius_left_m.mode)) {
      scalar(left, p.wheel_radius_left_m, u.wheel_radius_left_m.sigma, nominal.wheel_radius_left_m,
             &c->wheel_radius_left_m, o.default_wheel_radius_prior_sigma_m,
             o.max_observable_wheel_radius_sigma_m, 1e3, "mm");
    }
    if (!p.wheel_radius_shared && Estimated(p.wheel_radius_right_m.mode)) {
      scalar("right rear wheel radius", p.wheel_radius_right_m, u.wheel_radius_right_m.sigma,
             nominal.wheel_radius_right_m, &c->wheel_radius_right_m,
             o.default_wheel_radius_prior_sigma_m, o.max_observable_wheel_radius_sigma_m, 1e3, "mm");
    }
    if (Estimated(p.track_width_m.mode)) {
      scalar("track width", p.track_width_m, u.track_width_m.sigma, nominal.track_width_m,
             &c->track_width_m, o.default_track_width_prior_sigma_m,
             o.max_observable_track_width_sigma_m, 1e3, "mm");
    }
    if (Estimated(p.T_I_V.rotation.mode)) {
      rotation("T_I_V rotation", p.T_I_V.rotation, u.T_I_V.sigma_rot_deg, nominal.q_I_V,
               c->q_I_V.coeffs().data(), o.max_observable_vehicle_rotation_sigma_deg,
               {"vehicle frame rotation about the IMU x axis (roll)",
                "vehicle frame rotation about the IMU y axis (pitch)",
                "vehicle frame rotation about the IMU z axis (yaw)"});
    }
    if (Estimated(p.T_I_V.translation.mode)) {
      vector("T_I_V translation", p.T_I_V.translation, u.T_I_V.sigma_p_m, nominal.p_I_V,
             c->p_I_V.data(), o.max_observable_vehicle_translation_sigma_m,
             {"rear-axle x position (IMU frame)", "rear-axle y position (IMU frame)",
              "rear-axle z position (IMU frame)"});
    }
  }
  if (use_gnss && Estimated(p.p_I_A_m.mode)) {
    vector("p_I_A", p.p_I_A_m, u.p_I_A_m.sigma, nominal.p_I_A, c->p_I_A.data(),
           o.max_observable_lever_arm_sigma_m,
           {"GNSS antenna x lever arm (IMU frame)", "GNSS antenna y lever arm (IMU frame)",
            "GNSS antenna z lever arm (IMU frame)"});
  }
  return blocks;
}

// The result's uncertainty section from the observability analysis.
void FillUncertainty(const std::vector<CalibrationBlock>& blocks, const BlockObservability& obs,
                     io::CalibrationUncertainty* u) {
  for (size_t i = 0; i < blocks.size(); ++i) {
    const std::string& name = blocks[i].name;
    const Eigen::VectorXd& sigma = obs.sigma[i];
    const std::vector<bool>& flags = obs.observable[i];
    auto append = [](std::vector<bool>* out, const std::vector<bool>& f, size_t first) {
      if (out->size() < 6) out->resize(6, true);
      for (size_t k = 0; k < f.size(); ++k) (*out)[first + k] = f[k];
    };
    if (name == "T_I_L rotation") {
      u->T_I_L.sigma_rot_deg = Eigen::Vector3d(sigma * kRadToDeg);
      append(&u->T_I_L.observable, flags, 0);
    } else if (name == "T_I_L translation") {
      u->T_I_L.sigma_p_m = Eigen::Vector3d(sigma);
      append(&u->T_I_L.observable, flags, 3);
    } else if (name == "T_I_V rotation") {
      u->T_I_V.sigma_rot_deg = Eigen::Vector3d(sigma * kRadToDeg);
      append(&u->T_I_V.observable, flags, 0);
    } else if (name == "T_I_V translation") {
      u->T_I_V.sigma_p_m = Eigen::Vector3d(sigma);
      append(&u->T_I_V.observable, flags, 3);
    } else if (name == "p_I_A") {
      u->p_I_A_m.sigma = Eigen::Vector3d(sigma);
      u->p_I_A_m.observable = flags;
    } else {
      io::ScalarBlockInfo* info = name == "LiDAR-IMU time offset" ? &u->time_offset_lidar_imu_s
                                  : name == "right rear wheel radius" ? &u->wheel_radius_right_m
                                  : name == "track width"             ? &u->track_width_m
                                                                      : &u->wheel_radius_left_m;
      info->sigma = sigma(0);
      info->observable = flags[0];
    }
  }
}

// The initializer's keyframes are in a gravity-aligned frame of their own; GNSS brings them
// into ENU. Where the LiDAR odometry followed the drive, a 4-DoF alignment of its track does
// (Eq. K3-K5) and true is returned. Where it did not (a featureless road, traffic moving with
// the car: its track then misses the fixes by metres or is too short to give the yaw), every
// state the initializer derived from that track is unusable: the keyframes are rebuilt from
// GNSS, the IMU and the problem's wheels (estimation/gnss_inertial_keyframes.h), a warning says so, and false
// is returned (the caller then starts the LiDAR blocks from their nominal values).
bool PlaceKeyframesInEnu(const io::Dataset& dataset, const sensors::EnuConverter& enu,
                         const sensors::Calibration& calibration,
                         const OfflineCalibrationOptions& options, int num_threads,
                         const sensors::WheelSamples& wheel,
                         std::vector<estimation::Keyframe>* keyframes,
                         std::vector<std::string>* warnings) {
  std::vector<estimation::Keyframe> aligned = *keyframes;
  std::string failure;
  try {
    const estimation::GnssAlignment fit =
        estimation::AlignKeyframesToGnss(&aligned, dataset.gnss, enu, calibration.p_I_A);
    if (fit.rms_m <= options.max_odometry_to_gnss_rms_m) {
      *keyframes = std::move(aligned);
      return true;
    }
    failure = "its track misses the GNSS fixes by " + FormatFixed(fit.rms_m, 2) +
              " m RMS after alignment";
  } catch (const Error& e) {
    failure = e.what();
  }
  estimation::GnssInertialKeyframesOptions gnss_inertial;
  gnss_inertial.imu_noise = dataset.sensors.imu.noise;
  gnss_inertial.num_threads = num_threads;
  const estimation::GnssInertialKeyframes rebuilt = estimation::KeyframesFromGnssAndImu(
      keyframes, dataset.imu, wheel, dataset.gnss, enu, calibration, gnss_inertial);
  warnings->push_back(
      "the LiDAR odometry did not follow the drive (" + failure + "): the keyframes were "
      "rebuilt from GNSS and the IMU (" + std::to_string(rebuilt.placement.num_placed) +
      " on the fitted GNSS track, " + std::to_string(rebuilt.placement.num_bridged) +
      " bridged), and the LiDAR rotation, translation and time offset start from their nominal "
      "values");
  return false;
}

}  // namespace

OfflineCalibrationResult CalibrateDataset(const io::Dataset& dataset, const io::Problem& problem,
                                          const OfflineCalibrationOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  io::ValidateProblemForDataset(problem, dataset);
  if (!problem.sensors.lidar) {
    throw Error("problem " + problem.path +
                ": calibrations without the LiDAR (IMU, wheels and GNSS only) are not solved by "
                "this version of autocal; use a problem with the LiDAR");
  }
  OfflineCalibrationResult result;
  result.nominal = dataset.sensors.nominal_calibration;

  // 1. Sweeps.
  const int64_t num_sweeps = static_cast<int64_t>(dataset.lidar_sweeps.size());
  std::vector<lidar::LidarSweep> sweeps(static_cast<size_t>(num_sweeps));
  ParallelFor(0, num_sweeps, problem.solver.num_threads,
              [&](int64_t begin, int64_t end, int chunk) {
                for (int64_t i = begin; i < end; ++i) {
                  sweeps[static_cast<size_t>(i)] = dataset.LoadSweep(static_cast<size_t>(i));
                  // The first chunk's progress stands for all of them.
                  if (chunk == 0 && (i - begin) % 50 == 0) {
                    Report(options, "loading sweeps",
                           static_cast<double>(i - begin + 1) / static_cast<double>(end - begin),
                           0.0, 0.0);
                  }
                }
              });

  // 2. Initialization: no hand-measured guess needed.
  result.seconds_loading = SecondsSince(start);
  Report(options, "initializing", 0.0, 0.0, 0.0);
  estimation::CalibrationInitializerOptions init_options = options.initializer;
  init_options.imu_noise = dataset.sensors.imu.noise;
  init_options.p_I_L_prior = result.nominal.p_I_L;
  init_options.odometry.num_threads = problem.solver.num_threads;
  // A drive without turns (a highway) cannot determine the rotation and offset: the nominal
  // values stand in, and the observability analysis then says what the solve could fix.
  init_options.fallback_q_I_L = result.nominal.q_I_L;
  init_options.fallback_time_offset_s = result.nominal.time_offset_lidar_imu_s;
  result.initialization = estimation::InitializeLidarImu(dataset.imu, sweeps, init_options);
  const estimation::CalibrationInitialization& init = result.initialization;
  if (!init.ok) {
    throw Error("dataset " + dataset.directory + ": the drive cannot initialize the calibration: " +
                Join(init.problems, "; "));
  }
  result.seconds_initialization = SecondsSince(start) - result.seconds_loading;
  for (const std::string& fallback : init.fallbacks) {
    result.warnings.push_back("initialization: " + fallback);
  }
  Report(options, "initializing", 1.0, 0.0, 0.0);

  // 3. Batch solve from the initializer's calibration (fixed blocks keep the nominal value),
  //    with the wheel and GNSS factors and the priors of the problem.
  sensors::Calibration calibration = result.nominal;
  const io::ProblemCalibration& blocks = problem.calibration;
  if (Estimated(blocks.T_I_L.rotation.mode)) calibration.q_I_L = init.q_I_L;
  if (Estimated(blocks.T_I_L.translation.mode)) calibration.p_I_L = init.p_I_L;
  if (Estimated(blocks.time_offset_lidar_imu_s.mode)) {
    calibration.time_offset_lidar_imu_s = init.time_offset_lidar_imu_s;
  }
  estimation::LidarInertialBatchOptions batch_options = BatchOptions(dataset, problem);
  batch_options.keyframe_lead_s = init_options.keyframe_lead_s;
  batch_options.progress = [&](const estimation::LidarInertialBatchProgress& p) {
    const double per_iteration = p.elapsed_s / p.iteration;
    Report(options, "solving", static_cast<double>(p.iteration) / p.max_iterations, p.cost,
           per_iteration * (p.max_iterations - p.iteration));
  };
  std::vector<lidar::LidarSweep> keyframe_sweeps;
  std::vector<estimation::Keyframe> keyframes;
  // Every sweep_stride-th keyframe; the sweeps are not needed elsewhere any more: moved, not
  // copied.
  const size_t stride = static_cast<size_t>(problem.lidar.sweep_stride);
  for (size_t k = 0; k < init.keyframe_sweeps.size(); k += stride) {
    keyframe_sweeps.push_back(std::move(sweeps[static_cast<size_t>(init.keyframe_sweeps[k])]));
    keyframes.push_back(init.keyframes[k]);
  }
  sweeps.clear();
  if (keyframes.size() < 2) {
    throw Error("problem " + problem.path + ": lidar.sweep_stride " +
                std::to_string(problem.lidar.sweep_stride) + " leaves " +
                std::to_string(keyframes.size()) + " keyframe(s) of the " +
                std::to_string(init.keyframes.size()) + " the log gives; the solve needs two");
  }

  const bool use_wheel = problem.sensors.wheel && !dataset.wheel.empty();
  const bool use_gnss = problem.sensors.gnss && !dataset.gnss.empty();
  std::optional<sensors::EnuConverter> enu;
  if (use_gnss) {
    // W becomes the ENU frame at the first fix: GNSS fixes position and yaw.
    enu = sensors::EnuConverter::AtFirstFix(dataset.gnss);
    if (!PlaceKeyframesInEnu(dataset, *enu, calibration, options, problem.solver.num_threads,
                             use_wheel ? dataset.wheel : sensors::WheelSamples(), &keyframes,
                             &result.warnings)) {
      calibration.q_I_L = result.nominal.q_I_L;
      calibration.p_I_L = result.nominal.p_I_L;
      calibration.time_offset_lidar_imu_s = result.nominal.time_offset_lidar_imu_s;
    }
    batch_options.hold_first_pose = false;
    for (const sensors::GnssFix& fix : dataset.gnss) {
      result.gnss_positions_W.push_back(enu->ToEnu(fix.lat_deg, fix.lon_deg, fix.alt_m));
    }
  }
  const std::vector<CalibrationBlock> blocks_estimated =
      EstimatedBlocks(problem, dataset.sensors, options, use_wheel, use_gnss, &calibration);
  geometry::RightQuaternionManifold quaternion_manifold;  // outlives every solve
  batch_options.add_factors = [&](ceres::Problem* p, std::vector<estimation::Keyframe>* kfs,
                                  sensors::Calibration* c) {
    if (use_wheel) {
      p->AddParameterBlock(c->q_I_V.coeffs().data(), 4, &quaternion_manifold);
      estimation::KeyframeWheelOptions wheel;
      wheel.factor = factors::WheelFactorOptions::FromEncoderNoise(
          *dataset.sensors.wheel, result.nominal.wheel_radius_left_m,
          result.nominal.track_width_m);
      wheel.factor.shared_radius = blocks.wheel_radius_shared;
      wheel.loss = problem.loss.wheel;
      wheel.estimate_vehicle_rotation = Estimated(blocks.T_I_V.rotation.mode);
      wheel.estimate_vehicle_translation = Estimated(blocks.T_I_V.translation.mode);
      wheel.estimate_radii = Estimated(blocks.wheel_radius_left_m.mode);
      wheel.estimate_track_width = Estimated(blocks.track_width_m.mode);
      estimation::AddWheelFactors(p, dataset.imu, dataset.wheel, kfs, c, wheel);
    }
    if (use_gnss) {
      estimation::KeyframeGnssOptions gnss;
      gnss.loss = problem.loss.gnss;
      gnss.estimate_lever_arm = Estimated(blocks.p_I_A_m.mode);
      estimation::AddGnssFactors(p, dataset.gnss, *enu, kfs, c, gnss);
    }
    AddBlockPriors(blocks_estimated, problem.loss.prior, p);
  };
  BlockCovariance covariance;
  batch_options.compute_covariance = false;  // the joint one below covers every block
  batch_options.inspect_final_problem = [&](ceres::Problem* p) {
    covariance = ComputeBlockCovariance(blocks_estimated, p);
  };
  Report(options, "solving", 0.0, 0.0, 0.0);
  result.batch = estimation::SolveLidarInertialBatch(dataset.imu, keyframe_sweeps, &keyframes,
                                                     &calibration, batch_options);

  // 4. Observability and uncertainty: directions the drive did not excite are held at their
  //    prior value, the rest conditioned on it (Eq. C1).
  io::CalibrationFile& file = result.calibration;
  const estimation::LidarInertialBatchReport& batch = result.batch;
  const std::vector<std::string> implausible =
      ImplausibleDirections(blocks_estimated, covariance, options.max_prior_deviation_sigmas);
  if (!implausible.empty()) {
    throw Error("dataset " + dataset.directory +
                ": the calibration solve did not converge to a plausible result (" +
                Join(implausible, "; ") +
                "); nothing is written. The drive may not excite these blocks: fix them or "
                "give them priors in the problem file");
  }
  if (covariance.ok) {
    const BlockObservability observability =
        HoldUnobservableDirections(blocks_estimated, covariance);
    FillUncertainty(blocks_estimated, observability, &file.uncertainty);
    result.warnings.insert(result.warnings.end(), observability.warnings.begin(),
                           observability.warnings.end());
  } else {
    result.warnings.push_back(
        "the covariance of the calibration could not be computed; no sigma and no "
        "observability are reported");
  }
  if (blocks.wheel_radius_shared) calibration.wheel_radius_right_m = calibration.wheel_radius_left_m;
  if (problem.sensors.wheel && !use_wheel) {
    result.warnings.push_back("the dataset has no wheel samples: wheel blocks keep their nominal value");
  }
  file.value = calibration;

  file.solver["termination"] = batch.termination;
  file.solver["outer_iterations"] = std::to_string(batch.outer_iterations);
  file.solver["final_cost"] = std::to_string(batch.final_cost);
  file.solver["keyframes"] = std::to_string(keyframes.size());
  file.residuals["lidar"]["rms_m"] = batch.point_rms_m;
  file.residuals["lidar"]["associated_points"] = batch.associated_points;

  for (const estimation::Keyframe& kf : keyframes) {
    io::TrajectorySample sample;
    sample.t_ns = kf.t_ns;
    sample.T_W_I = geometry::Pose3d(kf.q_W_I.normalized(), kf.p_W_I);
    sample.v_W_I = kf.v_W_I;
    result.trajectory.push_back(sample);
  }
  result.seconds_total = SecondsSince(start);
  result.seconds_solve = result.seconds_total - result.seconds_loading - result.seconds_initialization;
  file.solver["seconds"] = std::to_string(result.seconds_total);
  file.solver["seconds_loading"] = std::to_string(result.seconds_loading);
  file.solver["seconds_initialization"] = std::to_string(result.seconds_initialization);
  file.solver["seconds_solve"] = std::to_string(result.seconds_solve);
  file.solver["seconds_association"] = std::to_string(batch.seconds_association);
  file.solver["seconds_ceres"] = std::to_string(batch.seconds_solver);
  return result;
}

void WriteCalibrationResult(const std::string& directory, const OfflineCalibrationResult& result) {
  std::error_code error;
  std::filesystem::create_directories(directory, error);
  if (error) throw Error("cannot create " + directory + ": " + error.message());
  io::WriteCalibrationYaml(directory + "/calibration.yaml", result.calibration);
  io::WriteTumTrajectory(directory + "/trajectory.tum", result.trajectory);
  const std::string csv_path = directory + "/calibration_per_iteration.csv";
  std::ofstream csv(csv_path);
  csv << "iteration,qx,qy,qz,qw,px_m,py_m,pz_m,time_offset_lidar_imu_s\n" << std::setprecision(12);
  for (size_t i = 0; i < result.batch.calibration_per_iteration.size(); ++i) {
    const sensors::Calibration& c = result.batch.calibration_per_iteration[i];
    csv << i + 1 << ',' << c.q_I_L.x() << ',' << c.q_I_L.y() << ',' << c.q_I_L.z() << ','
        << c.q_I_L.w() << ',' << c.p_I_L.x() << ',' << c.p_I_L.y() << ',' << c.p_I_L.z() << ','
        << c.time_offset_lidar_imu_s << '\n';
  }
  csv.close();
  if (!csv) throw Error("cannot write " + csv_path);
  const std::string html_path = directory + "/report.html";
  std::ofstream html(html_path);
  html << CalibrationReportHtml(result);
  html.close();
  if (!html) throw Error("cannot write " + html_path);
}

std::string FormatCalibrationSummary(const OfflineCalibrationResult& result) {
  const sensors::Calibration& c = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  std::ostringstream out;
  out << std::fixed;
  const Eigen::Vector3d rpy_deg = geometry::Log(c.q_I_L) * kRadToDeg;
  out << "T_I_L rotation (rotation vector, deg): " << std::setprecision(4) << rpy_deg.transpose();
  if (u.T_I_L.sigma_rot_deg) out << "   sigma " << u.T_I_L.sigma_rot_deg->transpose();
  out << "\nT_I_L translation (m):                " << c.p_I_L.transpose();
  if (u.T_I_L.sigma_p_m) out << "   sigma " << u.T_I_L.sigma_p_m->transpose();
  out << "\ntime offset lidar->imu (ms):          " << std::setprecision(3)
      << c.time_offset_lidar_imu_s * 1e3;
  if (u.time_offset_lidar_imu_s.sigma) {
    out << "   sigma " << *u.time_offset_lidar_imu_s.sigma * 1e3;
  }
  out << "\nLiDAR residual RMS (m):               " << std::setprecision(4)
      << result.batch.point_rms_m << " over " << result.batch.associated_points << " points\n";
  out << "solver: " << result.batch.outer_iterations << " outer iterations; "
      << std::setprecision(1) << result.seconds_total << " s (loading " << result.seconds_loading
      << " s, initialization " << result.seconds_initialization << " s, solve "
      << result.seconds_solve << " s: association " << result.batch.seconds_association
      << " s, Ceres " << result.batch.seconds_solver << " s)\n";
  for (const std::string& warning : result.warnings) out << "warning: " << warning << '\n';
  return out.str();
}

}  // namespace pipeline
}  // namespace autocal
