#include "window_settings.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/estimation/planar_rotation_rows.h"
#include "autocal/estimation/sliding_window_blocks.h"
#include "autocal/sensors/calibration_blocks.h"
#include "calibration_steps.h"
#include "problem_blocks.h"

namespace autocal {
namespace pipeline {

namespace {

// What the window estimates and its prior sigmas, from the problem and the dataset's stated
// nominal uncertainty. A block is estimated when its sensor takes part and the problem does not
// fix it. The window's priors are the problem's sigma in prior mode, else the sigma the dataset
// states, else the offline calibration's default (DefaultPriorSigma), so that both estimators
// assume the same of a nominal value nobody gave a sigma; a stated per-axis sigma whose axes
// differ stays per axis (axis_sigmas), as in the offline calibration (problem_blocks.cc). Blocks
// that share a switch (the vehicle frame's rotation and translation, the two radii or speed
// scales) share the wider sigma; a problem that estimates one and fixes the other is an
// autocal::Error, since the window would estimate both.
void SetWindowBlocks(const std::string& problem_path, const io::ProblemCalibration& problem,
                     const io::SensorsConfig& sensors, sensors::WheelForm form, bool use_wheel,
                     bool use_gnss, estimation::SlidingWindowOptions* w) {
  const OfflineCalibrationOptions offline;
  estimation::SlidingWindowBlockSetting previous{nullptr, nullptr};
  const char* previous_name = "";
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    // The blocks the window cannot estimate are refused in WindowOptions.
    if (!estimation::WindowSupports(info.id)) continue;
    const BlockSetting s = SettingOf(info.id, problem, sensors.nominal_uncertainty);
    const bool estimated = SensorUsed(info, use_wheel, use_gnss) &&
                           sensors::BlockInWheelForm(info.id, form) && Estimated(s.mode);
    const double default_sigma = DefaultPriorSigma(info.id, sensors, offline);
    const std::optional<Eigen::VectorXd> stated =
        s.mode == io::BlockMode::kPrior ? std::optional<Eigen::VectorXd>(s.prior_sigma)
                                        : s.nominal_sigma;
    const double sigma = stated ? stated->maxCoeff() : default_sigma;
    if (estimated && stated && stated->size() == 3 && stated->minCoeff() < sigma) {
      w->calibration_prior.axis_sigmas[info.id] = *stated;
    }
    const estimation::SlidingWindowBlockSetting block =
        estimation::BlockSettingOf(info.id, &w->estimate, &w->calibration_prior);
    if (block.estimate == previous.estimate && *block.estimate != estimated) {
      throw Error("problem " + problem_path + ": the online estimator estimates the " +
                  previous_name + " and the " + info.name +
                  " together; the problem fixes one and estimates the other");
    }
    *block.estimate = estimated;
    previous_name = info.name;
    *block.prior_sigma =
        block.prior_sigma == previous.prior_sigma ? std::max(*block.prior_sigma, sigma) : sigma;
    previous = block;
  }
}

// The problem's blocks that the window cannot estimate (estimation::WindowSupports): one
// autocal::Error naming the first that the problem estimates, and the wheel or GNSS clock
// offsets when the nominal one is not zero (the window reads both streams on the IMU clock), so
// that no result silently leaves them out.
void RefuseWhatTheWindowCannotDo(const io::Dataset& dataset, const io::Problem& problem,
                                 bool use_wheel, bool use_gnss) {
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    if (estimation::WindowSupports(info.id) || !SensorUsed(info, use_wheel, use_gnss) ||
        !sensors::BlockInWheelForm(info.id, dataset.wheel_form())) {
      continue;
    }
    if (Estimated(
            SettingOf(info.id, problem.calibration, dataset.sensors.nominal_uncertainty).mode)) {
      throw Error("problem " + problem.path + ": the online estimator does not estimate the " +
                  info.name + " yet; fix it in the problem file or use autocal_calibrate");
    }
  }
  const sensors::Calibration& nominal = dataset.sensors.nominal_calibration;
  const auto refuse_offset = [&](bool used, double offset_s, const char* sensor) {
    if (!used || offset_s == 0.0) return;
    throw Error("dataset " + dataset.directory + ": the online estimator reads the " + sensor +
                " on the IMU clock, and sensors.yaml states a " + sensor + " time offset of " +
                std::to_string(offset_s) + " s; it does not apply clock offsets yet");
  };
  refuse_offset(use_wheel, nominal.time_offset_wheel_imu_s, "wheel");
  refuse_offset(use_gnss, nominal.time_offset_gnss_imu_s, "GNSS");
}

// The blocks the problem fixes that the window could estimate and whose sensor it reads.
std::vector<sensors::CalibrationBlockId> TestedFixedBlocks(const io::SensorsConfig& sensors,
                                                           const io::Problem& problem,
                                                           bool use_wheel, bool use_gnss) {
  sensors::Calibration scratch = sensors.nominal_calibration;
  std::vector<sensors::CalibrationBlockId> out;
  for (const estimation::EstimatedBlock& b :
       FixedBlocks(problem, sensors, OfflineCalibrationOptions(), use_wheel, use_gnss, &scratch)) {
    const bool lidar = sensors::CalibrationBlock(b.id).sensor == sensors::BlockSensor::kLidar;
    if (estimation::WindowSupports(b.id) && (problem.sensors.lidar || !lidar)) {
      out.push_back(b.id);
    }
  }
  return out;
}

}  // namespace

estimation::SlidingWindowOptions WindowOptions(const io::Dataset& dataset,
                                               const io::Problem& problem, bool use_wheel,
                                               bool use_gnss,
                                               const OnlineEstimationOptions& options) {
  const io::ProblemCalibration& b = problem.calibration;
  if (b.wheel_radius_shared) {
    throw Error("problem " + problem.path +
                ": wheel_radius_shared is not supported by the "
                "online estimator (it estimates both radii)");
  }
  if (use_wheel &&
      Estimated(b.wheel_radius_left_m.mode) != Estimated(b.wheel_radius_right_m.mode)) {
    throw Error("problem " + problem.path +
                ": the online estimator estimates both wheel radii "
                "or neither; the problem fixes only one");
  }
  RefuseWhatTheWindowCannotDo(dataset, problem, use_wheel, use_gnss);
  estimation::SlidingWindowOptions w = options.window;
  w.imu = dataset.sensors.imu;
  if (dataset.sensors.wheel) w.wheel = *dataset.sensors.wheel;
  if (dataset.wheel_form() == sensors::WheelForm::kSpeedYawRate) {
    w.wheel.controller_track_m = ControllerTrackM(dataset, dataset.sensors.nominal_calibration);
  }
  w.loss = problem.loss;
  w.window_size = problem.window_size;
  w.pairing.partner_offsets = estimation::WindowPartnerOffsets(problem.window_size);
  w.solver.max_iterations = problem.solver.max_iterations;
  w.num_threads = problem.solver.num_threads;
  w.pairing.max_residuals_per_sweep = problem.lidar.max_points_per_sweep;
  w.pairing.residual_voxel_m = problem.lidar.voxel_m;
  w.pairing.residual_max_range_m = problem.window_max_range_m;
  w.initial_state_sigmas = options.initial_state_sigmas;
  // The rear axle's lateral and vertical speed rows, weighted for their correlated model error
  // (the correlated-error scaling, as in the offline calibration). Without them the wheel speeds
  // see the vehicle frame's pitch and yaw only through the cosine that scales the speed along x_V,
  // as the radii do: on the 60 s urban log the window drifted along that valley to 5.7 deg and
  // -0.47 % (docs/sliding_window.md).
  w.wheel_rows.non_holonomic = use_wheel;
  // The rows' body rate given the gyro (Eq. K14), from the spread of the log's rates sampled at
  // the wheels' rate, as the offline calibration conditions its rows.
  if (use_wheel && dataset.sensors.wheel && dataset.sensors.wheel->rate_hz > 0.0) {
    w.wheel_rows.body_rate_prior = sensors::BodyRatePrior::FitToLog(
        dataset.imu, 1.0 / dataset.sensors.wheel->rate_hz, w.wheel_rows.gyro_mean_span_s,
        w.imu.noise.GyroSampleSigmaRadS(w.imu.noise.update_rate_hz));
  }

  // The priors are the nominal calibration's, as in the offline calibration: the initializer's
  // values only start the window.
  w.calibration_prior.mean = dataset.sensors.nominal_calibration;
  SetWindowBlocks(problem.path, problem.calibration, dataset.sensors, dataset.wheel_form(),
                  use_wheel, use_gnss, &w);
  if (options.test_fixed_blocks) {
    w.tested_fixed_blocks = TestedFixedBlocks(dataset.sensors, problem, use_wheel, use_gnss);
  }
  return w;
}

double PlanarRotationSigma(const io::Dataset& dataset, const io::Problem& problem, bool use_wheel,
                           double keyframe_period_s, const Eigen::Quaterniond& q_I_V,
                           const estimation::WheelRowOptions& wheel_rows) {
  const std::optional<double>& setting = problem.calibration.roll_pitch_rate_sigma_rad_s;
  if (!use_wheel || !setting) return 0.0;
  if (*setting > 0.0) return *setting;
  return estimation::MeasurePlanarRotationSpreadOfLog(dataset.imu, q_I_V, keyframe_period_s,
                                                      wheel_rows.gyro_mean_span_s)
      .RowSigmaRadS();
}

void FillWindowUncertainty(const estimation::CalibrationCovariance& covariance,
                           io::CalibrationUncertainty* u) {
  for (size_t b = 0; b < covariance.names.size(); ++b) {
    const sensors::CalibrationBlockInfo* info = sensors::FindCalibrationBlock(covariance.names[b]);
    if (info == nullptr) continue;
    Eigen::VectorXd sigma(info->tangent_size);
    for (int k = 0; k < info->tangent_size; ++k) {
      const int i = covariance.offsets[b] + k;
      sigma(k) = std::sqrt(std::max(0.0, covariance.covariance(i, i)));
    }
    SetUncertainty(info->id, sigma, nullptr, u);
  }
}

void SetGnssStart(const sensors::EnuConverter& enu, const estimation::GnssInertialKeyframes& start,
                  const OnlineEstimationOptions& options,
                  estimation::SlidingWindowOptions* window_options,
                  std::vector<std::string>* warnings) {
  const std::optional<Eigen::Matrix<double, 15, 15>>& start_covariance = start.first_covariance;
  window_options->enu_origin_lla = Eigen::Vector3d(enu.lat0_deg(), enu.lon0_deg(), enu.alt0_m());
  estimation::SlidingWindowInitialStateSigmas& sigmas = window_options->initial_state_sigmas;
  sigmas.position_m = options.initial_position_sigma_with_gnss_m;
  sigmas.accel_bias_m_s2 = options.initial_accel_bias_sigma_with_gnss_m_s2;
  Eigen::Matrix<double, 15, 15> covariance = sigmas.InStatePriorOrder().cwiseAbs2().asDiagonal();
  if (start_covariance) covariance += 0.5 * (*start_covariance + start_covariance->transpose());
  window_options->initial_state_covariance = covariance;
  window_options->gnss_std_scale = start.gnss_std_scale;
  if (start.gnss_noise && !start.gnss_std_scale.IsOne()) {
    warnings->push_back(GnssNoiseWarning(
        *start.gnss_noise, "about the GNSS-inertial start over the first seconds,",
        "the start's states and the window's fixes take their std scaled by that until " +
            std::to_string(estimation::kMinGnssNoiseRows) +
            " rows of an axis group have left the window"));
  }
}

}  // namespace pipeline
}  // namespace autocal
