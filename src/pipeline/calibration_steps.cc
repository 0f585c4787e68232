#include "calibration_steps.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/time.h"
#include "autocal/estimation/calibration_observability.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/estimation/keyframe_solver_options.h"
#include "autocal/estimation/planar_rotation_rows.h"
#include "autocal/factors/planar_rotation_factor.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "autocal/factors/wheel_factor.h"
#include "autocal/sensors/calibration_blocks.h"
#include "autocal/sensors/imu_preintegration.h"
#include "estimation/keyframe_interpolation.h"
#include "problem_blocks.h"
#include "residual_groups.h"

namespace autocal {
namespace pipeline {

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

// How many of `samples` lie within the keyframes' time span.
template <typename Samples>
size_t CountWithin(const Samples& samples, const std::vector<estimation::Keyframe>& keyframes) {
  size_t n = 0;
  for (const auto& sample : samples) {
    n += sample.t_ns >= keyframes.front().t_ns && sample.t_ns <= keyframes.back().t_ns;
  }
  return n;
}

// Throws when a sensor gave factors at fewer than the problem's fraction of the keyframes it
// could serve: "wheel (10.1 Hz): 0 of 988 keyframes bracketed within max_wheel_gap_s = 0.250 s
// ...". A sensor on an estimated clock gives a keyframe one of its samples, each sample to
// one keyframe (docs/keyframe_factors.md, Eq. K17), so one slower than the keyframes can serve
// only as many as it has samples within their span.
// `limits` names the gap settings that decide it, `file` the samples (for when none falls
// inside the keyframes' span).
template <typename Samples>
void RequireCoverage(const io::Dataset& dataset, const std::string& sensor,
                     const sensors::SampleTiming& timing, int factors,
                     const std::vector<estimation::Keyframe>& keyframes, const std::string& limits,
                     double min_fraction, const Samples& samples, const std::string& file) {
  const size_t within = keyframes.empty() ? 0 : CountWithin(samples, keyframes);
  const size_t servable = std::min(keyframes.size(), within);
  const double needed = min_fraction * static_cast<double>(servable);
  if (factors > 0 && static_cast<double>(factors) >= needed) return;
  std::string message =
      "dataset " + dataset.directory + ": " + sensor + " (" + FormatFixed(timing.rate_hz(), 1) +
      " Hz): " + std::to_string(factors) + " of " + std::to_string(keyframes.size()) +
      " keyframes bracketed within " + limits +
      ", fewer than timing.min_factor_fraction = " + FormatFixed(min_fraction, 2) + " of the " +
      std::to_string(servable) + " it could serve";
  if (within == 0) {
    message += " (" + file + ": 0 of " + std::to_string(samples.size()) +
               " samples fall inside the keyframes' time span)";
  } else {
    message += " (" + file + ": median interval " + FormatFixed(timing.median_interval_s, 3) +
               " s, p99 " + FormatFixed(timing.p99_interval_s, 3) + " s, longest " +
               FormatFixed(timing.max_gap_s, 3) + " s)";
  }
  throw Error(message + "; nothing is written");
}

// The stamps of the wheel form's samples.
std::vector<int64_t> WheelStamps(const io::Dataset& dataset) {
  switch (dataset.wheel_form()) {
    case sensors::WheelForm::kLinearSpeeds:
      return sensors::StampsOf(dataset.wheel_speeds);
    case sensors::WheelForm::kSpeedYawRate:
      return sensors::StampsOf(dataset.odometry);
    case sensors::WheelForm::kAngularRates:
      break;
  }
  return sensors::StampsOf(dataset.wheel);
}

// The wheel form's samples for estimation::AddWheelFactors.
estimation::WheelData FormData(const io::Dataset& dataset, const sensors::Calibration& nominal) {
  estimation::WheelData data;
  data.form = dataset.wheel_form();
  data.rates = dataset.wheel;
  data.speeds = dataset.wheel_speeds;
  data.odometry = dataset.odometry;
  data.controller_track_m = ControllerTrackM(dataset, nominal);
  return data;
}

// The estimate switches of the form's scales (radii, speed scales or k_v) and track (b or
// b_eff), from the problem's settings of those blocks.
void EstimateFormBlocks(sensors::WheelForm form, const io::ProblemCalibration& b,
                        estimation::KeyframeWheelOptions* wheel) {
  const bool twist = form == sensors::WheelForm::kSpeedYawRate;
  const io::ScalarBlockSetting& scale = twist ? b.odometry_speed_scale
                                        : form == sensors::WheelForm::kLinearSpeeds
                                            ? b.wheel_speed_scale_left
                                            : b.wheel_radius_left_m;
  wheel->estimate_radii = Estimated(scale.mode);
  wheel->estimate_track_width = Estimated(twist ? b.effective_track_m.mode : b.track_width_m.mode);
}

// The span of the mean gyro the wheel rows take (Eq. K13): a vehicle's body rates change over
// more than 0.2 s, and 0.1 s left the straight-drive suite's pitch NEES at the band's edge.
constexpr double kWheelGyroMeanSpanS = 0.2;

[[noreturn]] void ThrowNoFactor(const io::Dataset& dataset, const std::string& sensor,
                                const std::string& reason) {
  throw Error("dataset " + dataset.directory + ": no " + sensor + " factor in the solve (" +
              reason + "); nothing is written");
}

}  // namespace

double ControllerTrackM(const io::Dataset& dataset, const sensors::Calibration& nominal) {
  const std::optional<sensors::WheelConfig>& config = dataset.sensors.wheel;
  return config && config->controller_track_m ? *config->controller_track_m
                                              : nominal.effective_track_m;
}

namespace {

factors::WheelFactorOptions FormNoise(const sensors::WheelConfig& config, sensors::WheelForm form,
                                      const sensors::Calibration& nominal) {
  switch (form) {
    case sensors::WheelForm::kLinearSpeeds:
      return factors::WheelFactorOptions::FromWheelSpeedNoise(config, nominal.track_width_m);
    case sensors::WheelForm::kSpeedYawRate:
      return factors::WheelFactorOptions::FromOdometryNoise(config);
    case sensors::WheelForm::kAngularRates:
      break;
  }
  return factors::WheelFactorOptions::FromEncoderNoise(config, nominal.wheel_radius_left_m,
                                                       nominal.track_width_m);
}

}  // namespace

void SetWheelNoise(const io::Dataset& dataset, const sensors::Calibration& nominal,
                   estimation::KeyframeWheelOptions* wheel) {
  const sensors::WheelConfig config = dataset.sensors.wheel.value_or(sensors::WheelConfig());
  wheel->factor = FormNoise(config, dataset.wheel_form(), nominal);
  wheel->factor.lateral_sigma_m_s = config.lateral_slip_sigma_m_s;
  wheel->cornering_compliance_rad_per_m_s2 = config.cornering_compliance_rad_per_m_s2;
}

TimingLimits DeriveTimingLimits(const io::Dataset& dataset, const io::Problem& problem,
                                bool use_wheel, bool use_gnss) {
  const std::string where = dataset.directory + "/";
  TimingLimits t;
  t.imu = sensors::MeasureTiming(sensors::StampsOf(dataset.imu), where + "imu.csv");
  if (use_wheel) {
    t.wheel = sensors::MeasureTiming(WheelStamps(dataset),
                                     where + sensors::WheelFormFile(dataset.wheel_form()));
  }
  if (use_gnss)
    t.gnss = sensors::MeasureTiming(sensors::StampsOf(dataset.gnss), where + "gnss.csv");
  const io::ProblemTiming& o = problem.timing;
  t.max_imu_gap_s = o.max_imu_gap_s.value_or(sensors::MaxBracketingGapS(t.imu));
  if (t.wheel) t.max_wheel_gap_s = o.max_wheel_gap_s.value_or(sensors::MaxBracketingGapS(*t.wheel));
  const sensors::SampleTiming* wheel = t.wheel ? &*t.wheel : nullptr;
  t.keyframe_period_s =
      o.keyframe_period_s.value_or(t.gnss ? sensors::KeyframePeriodS(*t.gnss, t.imu, wheel)
                                          : sensors::KeyframePeriodS(t.imu, wheel));
  if (t.gnss) {
    t.max_fix_gap_s = o.max_fix_gap_s.value_or(sensors::MaxBracketingGapS(*t.gnss));
    t.gnss_track_half_width_s =
        o.gnss_track_half_width_s.value_or(sensors::GnssTrackHalfWidthS(*t.gnss));
  }
  t.min_factor_fraction = o.min_factor_fraction;
  return t;
}

void RecordTiming(const TimingLimits& timing, bool without_lidar, io::CalibrationFile* file) {
  std::map<std::string, std::string>& solver = file->solver;
  solver["timing_imu_rate_hz"] = FormatFixed(timing.imu.rate_hz(), 3);
  solver["timing_max_imu_gap_s"] = FormatFixed(timing.max_imu_gap_s, 4);
  if (timing.wheel) {
    solver["timing_wheel_rate_hz"] = FormatFixed(timing.wheel->rate_hz(), 3);
    solver["timing_max_wheel_gap_s"] = FormatFixed(timing.max_wheel_gap_s, 4);
  }
  if (timing.gnss) {
    solver["timing_gnss_rate_hz"] = FormatFixed(timing.gnss->rate_hz(), 3);
    solver["timing_max_fix_gap_s"] = FormatFixed(timing.max_fix_gap_s, 4);
    solver["timing_gnss_track_half_width_s"] = FormatFixed(timing.gnss_track_half_width_s, 4);
  }
  if (without_lidar) solver["timing_keyframe_period_s"] = FormatFixed(timing.keyframe_period_s, 4);
}

estimation::GnssInertialKeyframesOptions GnssInertialStart(const io::Dataset& dataset,
                                                           const io::Problem& problem,
                                                           const TimingLimits& timing) {
  estimation::GnssInertialKeyframesOptions options;
  options.imu_noise = dataset.sensors.imu.noise;
  options.gravity_m_s2 = dataset.sensors.imu.gravity_m_s2;
  options.num_threads = problem.solver.num_threads;
  options.placement.half_width_s = timing.gnss_track_half_width_s;
  options.gnss.max_fix_gap_s = timing.max_fix_gap_s;
  options.gnss.max_imu_gap_s = timing.max_imu_gap_s;
  if (timing.wheel) options.wheel.max_wheel_gap_s = timing.max_wheel_gap_s;
  options.wheel.max_imu_gap_s = timing.max_imu_gap_s;
  SetWheelNoise(dataset, dataset.sensors.nominal_calibration, &options.wheel);
  return options;
}

estimation::WheelData StartWheelData(const io::Dataset& dataset, bool use_wheel) {
  return use_wheel ? FormData(dataset, dataset.sensors.nominal_calibration)
                   : estimation::WheelData();
}

std::vector<estimation::Keyframe> KeyframesEvery(const sensors::ImuSamples& imu, int64_t first_ns,
                                                 int64_t last_ns, int64_t period_ns,
                                                 std::vector<std::string>* warnings) {
  std::vector<estimation::Keyframe> keyframes;
  int64_t skipped = 0;
  for (int64_t t = first_ns; t <= last_ns; t += period_ns) {
    if (!keyframes.empty() && !sensors::ImuSampleBetween(imu, keyframes.back().t_ns, t)) {
      ++skipped;
      continue;
    }
    keyframes.emplace_back();
    keyframes.back().t_ns = t;
  }
  const std::string dropout = ImuDropoutWarning(imu, skipped, "the keyframes");
  if (!dropout.empty()) warnings->push_back(dropout);
  return keyframes;
}

std::string ImuDropoutWarning(const sensors::ImuSamples& imu, int64_t skipped,
                              const std::string& where) {
  if (skipped == 0 || imu.size() < 2) return "";
  size_t longest = 1;
  for (size_t i = 2; i < imu.size(); ++i) {
    if (imu[i].t_ns - imu[i - 1].t_ns > imu[longest].t_ns - imu[longest - 1].t_ns) longest = i;
  }
  const auto seconds_in = [&](size_t i) {
    return FormatFixed(NsToSeconds(imu[i].t_ns - imu.front().t_ns), 3);
  };
  return where + ": " + std::to_string(skipped) +
         " keyframe(s) fell in IMU dropouts (no IMU sample between them and the keyframe "
         "before) and were left out; the next keyframe's IMU factor spans each dropout, the IMU "
         "interpolated linearly across it (the log's longest IMU interval: " +
         FormatFixed(NsToSeconds(imu[longest].t_ns - imu[longest - 1].t_ns), 3) + " s, from " +
         seconds_in(longest - 1) + " to " + seconds_in(longest) + " s after its first sample)";
}

void SensorFactors::Add(ceres::Problem* p, std::vector<estimation::Keyframe>* keyframes,
                        sensors::Calibration* c) const {
  const io::ProblemCalibration& b = problem->calibration;
  if (use_wheel) {
    p->AddParameterBlock(c->q_I_V.coeffs().data(), 4, quaternion_manifold);
    estimation::KeyframeWheelOptions wheel;
    SetWheelNoise(*dataset, *nominal, &wheel);
    // The compliance too: it sets the lateral row's sigma in a turn.
    for (double* sigma : {&wheel.factor.speed_sigma_m_s, &wheel.factor.yaw_rate_sigma_rad_s,
                          &wheel.factor.lateral_sigma_m_s, &wheel.factor.vertical_sigma_m_s,
                          &wheel.cornering_compliance_rad_per_m_s2}) {
      *sigma *= wheel_noise_scale;
    }
    wheel.factor.shared_radius = b.wheel_radius_shared;
    // The yaw row's sigma holds at the track it was stated for, the nominal one (Eq. F22b),
    // whatever track a later problem (an outer iteration, a new pairing) starts from.
    if (dataset->wheel_form() != sensors::WheelForm::kSpeedYawRate) {
      wheel.factor.yaw_row_track_m = nominal->track_width_m;
    }
    wheel.loss = problem->loss.wheel;
    wheel.max_wheel_gap_s = timing->max_wheel_gap_s;
    wheel.max_imu_gap_s = timing->max_imu_gap_s;
    wheel.estimate_vehicle_rotation = Estimated(b.T_I_V.rotation.mode);
    wheel.estimate_vehicle_translation = Estimated(b.T_I_V.translation.mode);
    EstimateFormBlocks(dataset->wheel_form(), b, &wheel);
    wheel.estimate_time_offset = Estimated(b.time_offset_wheel_imu_s.mode);
    wheel.gravity_m_s2 = dataset->sensors.imu.gravity_m_s2;
    wheel.gyro_mean_span_s = kWheelGyroMeanSpanS;
    wheel.gyro_sample_sigma_rad_s =
        dataset->sensors.imu.noise.GyroSampleSigmaRadS(timing->imu.rate_hz());
    const int n = estimation::AddWheelFactors(p, dataset->imu, FormData(*dataset, *nominal),
                                              keyframes, c, wheel);
    const char* file = sensors::WheelFormFile(dataset->wheel_form());
    const std::string limits =
        "max_wheel_gap_s = " + FormatFixed(wheel.max_wheel_gap_s, 3) +
        " s (and IMU samples within max_imu_gap_s = " + FormatFixed(wheel.max_imu_gap_s, 4) +
        " s, IMU at " + FormatFixed(timing->imu.rate_hz(), 1) + " Hz)";
    const auto require = [&](const auto& samples) {
      RequireCoverage(*dataset, "wheel", *timing->wheel, n, *keyframes, limits,
                      timing->min_factor_fraction, samples, file);
    };
    switch (dataset->wheel_form()) {
      case sensors::WheelForm::kLinearSpeeds:
        require(dataset->wheel_speeds);
        break;
      case sensors::WheelForm::kSpeedYawRate:
        require(dataset->odometry);
        break;
      case sensors::WheelForm::kAngularRates:
        require(dataset->wheel);
        break;
    }
    if (b.roll_pitch_rate_sigma_rad_s) {
      estimation::PlanarRotationOptions planar;
      planar.sigma_rad_s = *b.roll_pitch_rate_sigma_rad_s;
      planar.max_imu_gap_s = wheel.max_imu_gap_s;
      planar.gyro_mean_span_s = wheel.gyro_mean_span_s;
      planar.loss = wheel.loss;
      const estimation::PlanarRotationRows rows =
          estimation::AddPlanarRotationFactors(p, dataset->imu, keyframes, c, planar);
      if (planar_rotation != nullptr) *planar_rotation = rows;
    }
  }
  if (use_gnss) {
    const estimation::KeyframeGnssOptions gnss = GnssOptions();
    const int n =
        estimation::AddGnssFactors(p, dataset->imu, dataset->gnss, *enu, keyframes, c, gnss);
    RequireCoverage(*dataset, "GNSS", *timing->gnss, n, *keyframes,
                    "max_fix_gap_s = " + FormatFixed(gnss.max_fix_gap_s, 3) + " s",
                    timing->min_factor_fraction, dataset->gnss, "gnss.csv");
  }
  estimation::AddBlockPriors(*blocks, problem->loss.prior, p);
}

estimation::KeyframeGnssOptions SensorFactors::GnssOptions() const {
  const io::ProblemCalibration& b = problem->calibration;
  estimation::KeyframeGnssOptions gnss;
  gnss.loss = problem->loss.gnss;
  gnss.max_fix_gap_s = timing->max_fix_gap_s;
  gnss.estimate_lever_arm = Estimated(b.p_I_A_m.mode);
  gnss.estimate_time_offset = Estimated(b.time_offset_gnss_imu_s.mode);
  gnss.gravity_m_s2 = dataset->sensors.imu.gravity_m_s2;
  gnss.max_imu_gap_s = timing->max_imu_gap_s;
  gnss.noise_scale = gnss_noise_scale;
  return gnss;
}

estimation::GnssNoiseFromResiduals MeasureGnssNoise(const SensorFactors& factors,
                                                    std::vector<estimation::Keyframe>* keyframes,
                                                    sensors::Calibration* c) {
  if (!factors.use_gnss) return {};
  return estimation::MeasureGnssNoise(factors.dataset->imu, factors.dataset->gnss, *factors.enu,
                                      keyframes, c, factors.GnssOptions());
}

std::string GnssNoiseWarning(const estimation::GnssNoiseFromResiduals& noise,
                             const std::string& about, const std::string& applied) {
  std::vector<std::string> scaled;
  const auto axis = [&](const char* name, const estimation::GnssAxisNoise& a) {
    if (a.scale == 1.0) return;
    char text[200];
    std::snprintf(text, sizeof(text), "the %s rows' %.2f times their stated std (%zu rows)", name,
                  a.robust_sigma, a.rows);
    scaled.push_back(text);
  };
  axis("horizontal", noise.horizontal);
  axis("vertical", noise.vertical);
  if (scaled.empty()) return "";
  return "GNSS: " + about +
         " the fixes scatter beyond their stated std (robust sigma of the whitened rows, "
         "Eq. N2): " +
         Join(scaled, ", ") + "; " + applied + ". " + kGnssScatterCauses;
}

void RecordGnssNoiseScale(const estimation::GnssStdScale& scale, io::CalibrationFile* file) {
  file->residuals["gnss"]["noise_scale_horizontal"] = scale.horizontal;
  file->residuals["gnss"]["noise_scale_vertical"] = scale.vertical;
}

void WhitenGnssRowsBeforeAlike(const estimation::GnssStdScale& scale,
                               std::map<std::string, SensorResiduals>* residuals) {
  const auto gnss = residuals->find("gnss");
  if (gnss == residuals->end()) return;
  std::vector<double>& rows = gnss->second.before;
  for (size_t i = 0; i < rows.size(); ++i) {
    rows[i] /= i % 3 == 2 ? scale.vertical : scale.horizontal;
  }
}

bool SensorFactors::PairingChanges(const std::vector<estimation::Keyframe>& keyframes,
                                   const sensors::Calibration& from,
                                   const sensors::Calibration& to) const {
  const io::ProblemCalibration& b = problem->calibration;
  const auto changes = [&](const std::vector<int64_t>& stamps, double from_s, double to_s,
                           double max_gap_s) {
    const int64_t max_gap_ns = SecondsToNs(max_gap_s);
    return estimation::internal::PairedSamples(stamps, keyframes, from_s, max_gap_ns) !=
           estimation::internal::PairedSamples(stamps, keyframes, to_s, max_gap_ns);
  };
  if (use_wheel && Estimated(b.time_offset_wheel_imu_s.mode) &&
      changes(WheelStamps(*dataset), from.time_offset_wheel_imu_s, to.time_offset_wheel_imu_s,
              timing->max_wheel_gap_s)) {
    return true;
  }
  return use_gnss && Estimated(b.time_offset_gnss_imu_s.mode) &&
         changes(sensors::StampsOf(dataset->gnss), from.time_offset_gnss_imu_s,
                 to.time_offset_gnss_imu_s, timing->max_fix_gap_s);
}

void RecordPlanarRotation(const estimation::PlanarRotationRows& rows, io::CalibrationFile* file) {
  if (rows.added == 0) return;
  const auto pair = [](const Eigen::Vector2d& v, int digits) {
    return FormatFixed(v.x(), digits) + " " + FormatFixed(v.y(), digits);
  };
  file->solver["planar_rotation_rows"] = std::to_string(rows.added);
  file->solver["planar_rotation_sigma_rad_s"] = FormatFixed(rows.sigma_rad_s, 5);
  if (rows.spread.samples == 0) return;
  file->solver["planar_rotation_spread_rad_s"] = pair(rows.spread.sigma_rad_s, 5);
  file->solver["planar_rotation_correlation_scale"] = pair(rows.spread.correlation_scale, 2);
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
  const char* wheel_file = sensors::WheelFormFile(dataset.wheel_form());
  switch (dataset.wheel_form()) {
    case sensors::WheelForm::kAngularRates:
      require(use_wheel, dataset.wheel, wheel_file);
      break;
    case sensors::WheelForm::kLinearSpeeds:
      require(use_wheel, dataset.wheel_speeds, wheel_file);
      break;
    case sensors::WheelForm::kSpeedYawRate:
      require(use_wheel, dataset.odometry, wheel_file);
      break;
  }
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
  require(use_wheel, counters.wheel_accepted, dataset.wheel_sample_count(), "wheel",
          sensors::WheelFormFile(dataset.wheel_form()));
  require(use_gnss, counters.gnss_accepted, dataset.gnss.size(), "GNSS", "gnss.csv");
}

void RequireLidarFactors(const io::Dataset& dataset, const io::Problem& problem,
                         size_t num_keyframes, const OfflineCalibrationResult& result) {
  if (problem.sensors.lidar && result.batch.associated_points == 0) {
    ThrowNoFactor(dataset, "LiDAR",
                  "lidar.csv: no point of the " + std::to_string(num_keyframes) +
                      " keyframe sweeps was associated with a plane");
  }
}

int SolverIterations(const ceres::Solver::Summary& summary) {
  return static_cast<int>(summary.iterations.size()) - 1;
}

ceres::Solver::Options JointSolverOptions(const io::Problem& problem, int max_iterations) {
  return estimation::KeyframeSolverOptions(max_iterations, problem.solver.num_threads);
}

void SolveAgainAfterHolding(const io::Problem& problem,
                            const std::vector<estimation::EstimatedBlock>& blocks_estimated,
                            const estimation::BlockObservability& observability,
                            const sensors::Calibration& solved, sensors::Calibration* calibration,
                            ceres::Problem* p, OfflineCalibrationResult* result,
                            int max_iterations) {
  if (!estimation::AnyHeld(observability)) return;
  // From the solve's values with the held directions at their prior: the start does not depend
  // on the covariance's last digits (Eq. C1's step does), so identical runs give identical
  // values.
  *calibration = solved;
  estimation::SetHeldDirectionsToPrior(blocks_estimated, observability);
  const std::vector<ceres::ResidualBlockId> pins =
      estimation::AddHeldDirectionPriors(blocks_estimated, observability, p);
  ceres::Solver::Summary summary;
  ceres::Solve(JointSolverOptions(
                   problem, max_iterations > 0 ? max_iterations : problem.solver.max_iterations),
               p, &summary);
  if (!summary.IsSolutionUsable()) {
    throw Error("the solve with the unobservable directions held failed: " + summary.message);
  }
  result->calibration.solver["iterations_after_holding"] =
      std::to_string(SolverIterations(summary));
  if (summary.termination_type == ceres::NO_CONVERGENCE) {
    result->warnings.push_back(
        "the solve with the unobservable directions held stopped at its iteration limit (" +
        std::to_string(SolverIterations(summary)) +
        ") before converging: the trajectory and the kept directions may be off; raise "
        "solver.max_iterations");
  }
  estimation::SetHeldDirectionsToPrior(blocks_estimated, observability);
  for (ceres::ResidualBlockId pin : pins) p->RemoveResidualBlock(pin);
}

void RequirePlausible(const io::Dataset& dataset, const OfflineCalibrationOptions& options,
                      const std::vector<estimation::EstimatedBlock>& blocks_estimated,
                      const estimation::BlockCovariance& covariance) {
  const std::vector<std::string> implausible = estimation::ImplausibleDirections(
      blocks_estimated, covariance, options.max_prior_deviation_sigmas);
  if (!implausible.empty()) {
    throw Error("dataset " + dataset.directory +
                ": the calibration solve did not converge to a plausible result (" +
                Join(implausible, "; ") +
                "); nothing is written. The drive may not excite these blocks (fix them or give "
                "them priors in the problem file), or their nominal values lie farther from "
                "what the drive measures than their stated sigmas allow");
  }
}

void WarnOfFixedDirectionsTheDataMove(const io::Problem& problem, const io::SensorsConfig& sensors,
                                      const OfflineCalibrationOptions& options, bool use_wheel,
                                      bool use_gnss, sensors::Calibration* calibration,
                                      ceres::Problem* p, std::vector<std::string>* warnings) {
  const std::vector<estimation::EstimatedBlock> fixed =
      FixedBlocks(problem, sensors, options, use_wheel, use_gnss, calibration);
  // The exact rows and the points' sandwich each take a pass over the problem: only for a fixed
  // block that is a parameter of it (a wheel or GNSS clock fixed at zero, the default, is not).
  if (std::none_of(fixed.begin(), fixed.end(), [p](const estimation::EstimatedBlock& b) {
        return p->HasParameterBlock(b.data);
      })) {
    return;
  }
  estimation::ScatterSettings scatter;
  if (options.scatter_stretches > 0) {
    scatter = {SensorSources(p), options.scatter_stretches, options.scatter_significance};
  }
  for (const estimation::FixedDirectionMove& moved : estimation::FixedDirectionsTheDataMove(
           fixed, p, problem.solver.num_threads, options.max_fixed_block_step_sigmas,
           ExactResidualBlocks(*p), LidarSandwich(p), scatter)) {
    warnings->push_back(moved.text + options.fixed_block_advice);
  }
}

estimation::ScaledInformation LidarSandwich(ceres::Problem* problem) {
  estimation::ScaledInformation out;
  std::vector<ceres::ResidualBlockId> ids;
  problem->GetResidualBlocks(&ids);
  const std::optional<factors::SandwichRatio> ratio =
      PointGroupDistances(problem, ids, &out.residual_blocks);
  out.scale = ratio ? 1.0 / ratio->kappa() : 1.0;
  return out;
}

std::vector<ceres::ResidualBlockId> ExactResidualBlocks(const ceres::Problem& problem) {
  std::vector<ceres::ResidualBlockId> ids;
  problem.GetResidualBlocks(&ids);
  std::vector<ceres::ResidualBlockId> exact;
  for (const ceres::ResidualBlockId id : ids) {
    const ceres::CostFunction* f = problem.GetCostFunctionForResidualBlock(id);
    if (dynamic_cast<const factors::PointToSweepPlaneGroupFactor*>(f) == nullptr &&
        dynamic_cast<const factors::PlanarRotationFactor*>(f) == nullptr) {
      exact.push_back(id);
    }
  }
  return exact;
}

estimation::BlockCovariance PosteriorCovariance(
    const std::vector<estimation::EstimatedBlock>& blocks_estimated, ceres::Problem* problem,
    int num_threads, std::vector<std::string>* warnings, const estimation::ScaledInformation& lidar,
    estimation::CovarianceOrdering* ordering) {
  const std::vector<ceres::ResidualBlockId> exact = ExactResidualBlocks(*problem);
  const estimation::BlockCovariance covariance = estimation::ComputeBlockCovariance(
      blocks_estimated, problem, num_threads, exact, lidar, ordering);
  if (covariance.ok) return covariance;
  warnings->push_back(
      "covariance: the cost's exact Hessian is not positive definite at the solution (the solve "
      "is not at a minimum along some direction); the sigmas are Gauss-Newton's, which can count "
      "the measurements' noise as information");
  return estimation::ComputeBlockCovariance(blocks_estimated, problem, num_threads, {}, lidar,
                                            ordering);
}

namespace {

// The block direction of a stacked coordinate, in words.
std::string DirectionName(const std::vector<estimation::EstimatedBlock>& blocks,
                          const std::vector<int>& offsets, int coordinate) {
  for (size_t b = blocks.size(); b-- > 0;) {
    const int direction = coordinate - offsets[b];
    if (direction >= 0 && direction < blocks[b].size) {
      return blocks[b].direction_names[static_cast<size_t>(direction)];
    }
  }
  return "coordinate " + std::to_string(coordinate);
}

// A source's largest sqrt(observed / expected) over the directions Eq. C8 judges where its
// share is at least a tenth of J^T J's variance; 0 when it informs none.
double LargestScatterRatio(const estimation::StretchScatter& scatter,
                           const estimation::StretchScatter::Source& source) {
  double largest = 0.0;
  for (int c = 0; c < static_cast<int>(source.observed.rows()); ++c) {
    if (estimation::JudgesScatter(source, c) && source.model(c, c) >= 0.1 * scatter.variance(c)) {
      largest = std::max(largest, std::sqrt(source.observed(c, c) / source.expected(c, c)));
    }
  }
  return largest;
}

// One warning per source that widens a sigma, naming the direction it widens most.
std::vector<std::string> ScatterWarnings(const std::vector<estimation::EstimatedBlock>& blocks,
                                         const estimation::StretchScatter& scatter,
                                         const std::vector<estimation::ScatterExcess>& excess) {
  std::vector<std::string> named;
  std::vector<std::string> out;
  for (const estimation::ScatterExcess& e : excess) {  // largest sigma factor first
    if (std::find(named.begin(), named.end(), e.source) != named.end()) continue;
    named.push_back(e.source);
    const auto directions = std::count_if(
        excess.begin(), excess.end(), [&](const auto& other) { return other.source == e.source; });
    out.push_back(e.source + " rows: over " + std::to_string(scatter.stretches) +
                  " stretches of the log their share of the " +
                  DirectionName(blocks, scatter.offsets, e.coordinate) + " scatters " +
                  FormatFixed(e.ratio, 1) +
                  " times as widely as their noise model says (errors that last for stretches "
                  "of the drive, or noise larger than stated); its sigma is widened " +
                  FormatFixed(e.sigma_factor, 2) + " times (" + std::to_string(directions) +
                  " direction(s) widened, Eq. C8)");
  }
  return out;
}

}  // namespace

std::vector<estimation::ResidualSource> SensorSources(ceres::Problem* problem) {
  std::vector<estimation::ResidualSource> sources = ResidualSources(problem);
  sources.erase(std::remove_if(sources.begin(), sources.end(),
                               [](const auto& source) { return source.name == "priors"; }),
                sources.end());
  return sources;
}

void CheckScatterOptions(const OfflineCalibrationOptions& options) {
  const double significance = options.scatter_significance;
  if (options.scatter_stretches < 0 || options.scatter_stretches == 1 || !(significance > 0.0) ||
      !(significance < 1.0)) {
    throw Error(
        "OfflineCalibrationOptions: scatter_stretches must be 0 (no test) or at least 2, "
        "and scatter_significance in (0, 1); got " +
        std::to_string(options.scatter_stretches) + " and " + std::to_string(significance));
  }
}

estimation::BlockCovariance WidenedForScatter(
    const std::vector<estimation::EstimatedBlock>& blocks_estimated, ceres::Problem* problem,
    const estimation::BlockCovariance& covariance, const OfflineCalibrationOptions& options,
    int num_threads, estimation::CovarianceOrdering* ordering, OfflineCalibrationResult* result) {
  if (options.scatter_stretches == 0 || !covariance.ok || blocks_estimated.empty()) {
    return covariance;
  }
  const std::vector<estimation::ResidualSource> sources = SensorSources(problem);
  for (const estimation::ResidualSource& source : sources) {
    if (source.residual_blocks.size() >= static_cast<size_t>(options.scatter_stretches)) continue;
    result->warnings.push_back(
        source.name + " rows: " + std::to_string(source.residual_blocks.size()) +
        " factors, fewer than the " + std::to_string(options.scatter_stretches) +
        " stretches of the scatter test (Eq. C8): their scatter over the log is not tested");
  }
  const estimation::StretchScatter scatter = estimation::ComputeStretchScatter(
      blocks_estimated, problem, sources, options.scatter_stretches, num_threads, ordering);
  if (!scatter.ok) {
    result->warnings.push_back(
        "the rows' scatter over the log could not be computed (Eq. C8): the sigmas are those "
        "of the sensors' noise model alone");
    return covariance;
  }
  for (const estimation::StretchScatter::Source& source : scatter.sources) {
    const double ratio = LargestScatterRatio(scatter, source);
    if (ratio > 0.0) result->calibration.residuals[source.name]["stretch_scatter_ratio"] = ratio;
  }
  std::vector<estimation::ScatterExcess> excess;
  const estimation::BlockCovariance widened = estimation::WidenedForScatter(
      covariance, scatter, options.scatter_significance,
      estimation::StackedPriorVariances(blocks_estimated, scatter.offsets), &excess);
  for (std::string& warning : ScatterWarnings(blocks_estimated, scatter, excess)) {
    result->warnings.push_back(std::move(warning));
  }
  return widened;
}

void RecordPosterior(const std::vector<estimation::EstimatedBlock>& blocks_estimated,
                     const estimation::BlockCovariance& covariance,
                     const estimation::BlockCovariance& widened, const sensors::Calibration& solved,
                     OfflineCalibrationResult* result) {
  estimation::CalibrationPosterior& posterior = result->posterior;
  posterior.solved = solved;
  posterior.blocks = blocks_estimated;
  for (estimation::EstimatedBlock& block : posterior.blocks) block.data = nullptr;
  posterior.covariance = covariance;
  posterior.widened = widened;
}

void RecordBoundAtTruth(const OfflineCalibrationOptions& options,
                        const std::vector<estimation::EstimatedBlock>& blocks_estimated,
                        std::vector<estimation::Keyframe>* keyframes,
                        sensors::Calibration* calibration, ceres::Problem* problem, int num_threads,
                        OfflineCalibrationResult* result,
                        const estimation::ScaledInformation& lidar,
                        estimation::CovarianceOrdering* ordering) {
  if (!options.set_to_truth) return;
  const std::vector<estimation::Keyframe> solved_keyframes = *keyframes;
  const sensors::Calibration solved = *calibration;
  options.set_to_truth(keyframes, calibration);
  estimation::ErrorBudget budget = estimation::ComputeErrorBudget(
      blocks_estimated, problem, ResidualSources(problem), num_threads, lidar, ordering);
  const estimation::BlockCovariance bound = budget.scaled_covariance;
  Eigen::VectorXd error(bound.matrix.rows());
  for (size_t b = 0; b < blocks_estimated.size() && bound.ok; ++b) {
    const estimation::EstimatedBlock& block = blocks_estimated[b];
    const sensors::CalibrationBlockInfo& info = sensors::CalibrationBlock(block.id);
    error.segment(bound.offsets[b], block.size) =
        estimation::BlockMinus(block, info.const_values(*calibration), info.const_values(solved));
  }
  // Element by element: the problem's blocks point into these objects.
  for (size_t k = 0; k < keyframes->size(); ++k) (*keyframes)[k] = solved_keyframes[k];
  *calibration = solved;
  if (!bound.ok) {
    result->warnings.push_back(
        "the information at the truth is singular: no Cramer-Rao bound is reported");
    return;
  }
  result->bound = bound;
  result->error_at_bound = error;
  if (budget.ok) {
    result->error_budget = std::move(budget);
  } else {
    result->warnings.push_back(
        "the residuals at the truth did not evaluate: the error budget is not reported");
  }
}

estimation::BlockObservability Observe(
    const io::Dataset& dataset, const OfflineCalibrationOptions& options,
    const std::vector<estimation::EstimatedBlock>& blocks_estimated,
    const estimation::BlockCovariance& solved, const estimation::BlockCovariance& covariance,
    OfflineCalibrationResult* result) {
  RequirePlausible(dataset, options, blocks_estimated, solved);
  if (!covariance.ok) {
    result->warnings.push_back(
        "the covariance of the calibration could not be computed; no sigma and no "
        "observability are reported");
    return {};
  }
  const estimation::BlockObservability observability =
      estimation::HoldUnobservableDirections(blocks_estimated, covariance);
  FillUncertainty(blocks_estimated, observability, &result->calibration.uncertainty);
  if (estimation::AllHeld(observability)) {
    // The calibration written is the nominal one; only the trajectory is an estimate.
    size_t directions = 0;
    for (const std::vector<bool>& held : observability.held) directions += held.size();
    result->warnings.push_back("nothing is calibrated: the drive determines none of the " +
                               std::to_string(directions) +
                               " directions the problem estimates, and every block keeps its "
                               "nominal value (the trajectory is estimated)");
  }
  result->warnings.insert(result->warnings.end(), observability.warnings.begin(),
                          observability.warnings.end());
  return observability;
}

void GiveBothWheelsTheSharedRadius(const io::Problem& problem, io::CalibrationFile* file) {
  if (!problem.calibration.wheel_radius_shared) return;
  file->value.wheel_radius_right_m = file->value.wheel_radius_left_m;
  file->uncertainty.wheel_radius_right_m = file->uncertainty.wheel_radius_left_m;
}

void Conclude(const io::Dataset& dataset, const io::Problem& problem,
              const std::vector<estimation::Keyframe>& keyframes, sensors::Calibration* calibration,
              std::chrono::steady_clock::time_point start, OfflineCalibrationResult* result) {
  io::CalibrationFile& file = result->calibration;
  if (problem.calibration.wheel_radius_shared) {
    calibration->wheel_radius_right_m = calibration->wheel_radius_left_m;
  }
  if (problem.sensors.wheel && dataset.wheel_sample_count() == 0) {
    result->warnings.push_back(
        "the dataset has no wheel samples: wheel blocks keep their nominal value");
  }
  file.value = *calibration;
  GiveBothWheelsTheSharedRadius(problem, &file);
  file.solver["keyframes"] = std::to_string(keyframes.size());
  for (const estimation::Keyframe& kf : keyframes) {
    io::TrajectorySample sample;
    sample.t_ns = kf.t_ns;
    sample.T_W_I = geometry::Pose3d(kf.q_W_I.normalized(), kf.p_W_I);
    sample.v_W_I = kf.v_W_I;
    result->trajectory.push_back(sample);
  }
  for (const auto& [sensor, residuals] : result->whitened_residuals) {
    if (residuals.after.empty()) continue;
    std::map<std::string, double>& statistics = file.residuals[sensor];
    for (const auto& [name, value] : WhitenedStatistics(residuals.after, sensor == "gnss")) {
      statistics[name] = value;
    }
    if (residuals.factors > 0) {
      statistics["factors"] = static_cast<double>(residuals.factors);
      statistics["factors_downweighted_by_loss"] =
          static_cast<double>(residuals.factors_downweighted);
      statistics["whitened_rms_not_downweighted"] = residuals.rms_not_downweighted;
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
