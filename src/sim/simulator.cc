#include "autocal/sim/simulator.h"

#include <GeographicLib/LocalCartesian.hpp>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "sim/random_streams.h"
#include "sim/simulation_options_check.h"

namespace autocal {
namespace sim {
namespace {

// Uniform offsets in [-jitter_s, jitter_s] from a stream, in ns; zeros without jitter (and
// then nothing is drawn).
class StampJitter {
 public:
  StampJitter(double jitter_s, uint64_t seed, Stream stream)
      : jitter_s_(jitter_s), rng_(RandomStream(seed, stream)) {}
  bool on() const { return jitter_s_ > 0.0; }
  int64_t Next() {
    if (!on()) return 0;
    return SecondsToNs(jitter_s_ * (2.0 * uniform_(rng_) - 1.0));
  }
  std::mt19937_64& rng() { return rng_; }

 private:
  double jitter_s_;
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
};

// Measurement instant k of a grid of period dt_ns, jittered and then kept in [0, end_ns].
int64_t JitteredInstant(int64_t k, int64_t dt_ns, int64_t end_ns, StampJitter* jitter) {
  if (!jitter->on()) return k * dt_ns;
  const int64_t t = k * dt_ns + jitter->Next();
  return std::min(std::max<int64_t>(t, 0), end_ns);
}

// Arrival of each measurement (same clock as `instants`) when they are delivered in groups of
// `burst` consecutive ones: a group leaves when its last member is measured, and member j
// arrives j * span / burst after that. Without bursts, at its instant.
std::vector<int64_t> ArrivalTimes(const std::vector<int64_t>& instants, int burst, double span_s) {
  if (burst <= 1) return instants;
  const int64_t n = static_cast<int64_t>(instants.size());
  std::vector<int64_t> arrivals(instants.size());
  for (int64_t k = 0; k < n; ++k) {
    const int64_t last = std::min(n - 1, (k / burst) * burst + burst - 1);
    arrivals[k] = instants[last] + SecondsToNs(span_s * (k % burst) / burst);
  }
  return arrivals;
}

}  // namespace

Simulator::Simulator(const SimulationOptions& options) : options_(options) {
  internal::ValidateSimulationOptions(options_);
  // The truth carries the simulated clocks (groundtruth/calibration.yaml, the bound at the truth).
  options_.true_calibration.time_offset_wheel_imu_s = options_.wheel.time_offset_wheel_imu_s;
  options_.true_calibration.time_offset_gnss_imu_s = options_.gnss.time_offset_gnss_imu_s;
  ScenarioOptions scenario_options;
  scenario_options.type = options_.scenario;
  scenario_options.duration_s = options_.duration_s;
  scenario_options.seed = options_.seed;
  scenario_options.dynamics = options_.dynamics;
  scenario_ = BuildScenario(scenario_options);

  const sensors::Calibration& truth = options_.true_calibration;
  T_V_I_ = geometry::Pose3d(truth.q_I_V, truth.p_I_V).Inverse();
  T_V_L_ = T_V_I_ * geometry::Pose3d(truth.q_I_L, truth.p_I_L);

  // Nominal calibration: the truth perturbed (rotations on the right, in the body frame).
  std::mt19937_64 rng = RandomStream(options_.seed, Stream::kNominal);
  std::normal_distribution<double> normal(0.0, 1.0);
  const NominalPerturbation& np = options_.nominal_perturbation;
  auto rotation = [&]() -> Eigen::Quaterniond {
    const Eigen::Vector3d phi = DrawVector3([&] { return normal(rng); });
    return geometry::Exp(Eigen::Vector3d(np.rotation_deg * kDegToRad * phi));
  };
  auto translation = [&]() -> Eigen::Vector3d {
    return DrawVector3([&] { return normal(rng); }) * np.translation_m;
  };
  nominal_ = truth;
  nominal_.q_I_L = (truth.q_I_L * rotation()).normalized();
  nominal_.p_I_L = truth.p_I_L + translation();
  nominal_.time_offset_lidar_imu_s = truth.time_offset_lidar_imu_s + np.time_offset_s * normal(rng);
  nominal_.q_I_V = (truth.q_I_V * rotation()).normalized();
  if (np.q_I_V) nominal_.q_I_V = np.q_I_V->normalized();
  nominal_.p_I_V = truth.p_I_V + translation();
  nominal_.p_I_A = truth.p_I_A + translation();
  nominal_.wheel_radius_left_m = options_.nominal_wheel_radius_m;
  nominal_.wheel_radius_right_m = options_.nominal_wheel_radius_m;
  nominal_.track_width_m = options_.nominal_track_width_m;
  // The wheel forms' scales are 1 as the vehicle reports them; the effective track is the
  // physical one.
  nominal_.wheel_speed_scale_left = 1.0;
  nominal_.wheel_speed_scale_right = 1.0;
  nominal_.odometry_speed_scale = 1.0;
  nominal_.effective_track_m = options_.nominal_track_width_m;
  // The sensors' clocks are unknown to a nominal guess.
  nominal_.time_offset_wheel_imu_s = 0.0;
  nominal_.time_offset_gnss_imu_s = 0.0;

  // Sweeps: the first one starts 50 ms after t = 0 on the IMU clock; every sweep lies inside
  // [0, duration_s] on the IMU clock.
  const sensors::LidarConfig& l = options_.lidar.config;
  const double offset = truth.time_offset_lidar_imu_s;
  first_sweep_stamp_ns_ = options_.start_time_ns + SecondsToNs(0.05 - offset);
  const double period = 1.0 / l.rate_hz;
  num_columns_ = static_cast<int>(std::lround(360.0 / l.azimuth_resolution_deg));
  num_sweeps_ = 0;
  if (options_.lidar.enabled) {
    while (TimeOf(SweepStamp(num_sweeps_)) + offset + period <= options_.duration_s) ++num_sweeps_;
  }
  // The head spins counter-clockwise about z_L, starting behind the sensor (azimuth -pi);
  // beams are spread evenly between the configured elevations.
  beam_directions_.resize(static_cast<size_t>(num_columns_) * l.num_beams);
  for (int c = 0; c < num_columns_; ++c) {
    const double azimuth = -M_PI + 2.0 * M_PI * c / num_columns_;
    for (int b = 0; b < l.num_beams; ++b) {
      const double f = l.num_beams == 1 ? 0.5 : static_cast<double>(b) / (l.num_beams - 1);
      const double elevation =
          (l.min_elevation_deg + f * (l.max_elevation_deg - l.min_elevation_deg)) * kDegToRad;
      beam_directions_[static_cast<size_t>(c) * l.num_beams + b] =
          Eigen::Vector3d(std::cos(azimuth) * std::cos(elevation),
                          std::sin(azimuth) * std::cos(elevation), std::sin(elevation));
    }
  }
}

io::SensorsConfig Simulator::sensors_config() const {
  io::SensorsConfig config;
  config.imu.noise = options_.imu.noise;
  config.imu.noise.gyroscope_noise_density *= options_.imu.noise_scale;
  config.imu.noise.gyroscope_random_walk *= options_.imu.RandomWalkScale();
  config.imu.noise.accelerometer_noise_density *= options_.imu.noise_scale;
  config.imu.noise.accelerometer_random_walk *= options_.imu.RandomWalkScale();
  config.imu.gravity_m_s2 = options_.imu.gravity_m_s2;
  if (options_.lidar.enabled) config.lidar = options_.lidar.config;
  if (options_.wheel.enabled) {
    config.wheel = options_.wheel.config;
    // The stated slip covers the simulated one (Eq. K6c).
    double& compliance = config.wheel->cornering_compliance_rad_per_m_s2;
    compliance = std::max(compliance, options_.dynamics.rear_slip_per_lateral_accel);
  }
  if (options_.gnss.enabled) config.gnss = options_.gnss.config;
  config.nominal_calibration = nominal_;
  const NominalPerturbation& np = options_.nominal_perturbation;
  if (np.state_uncertainty) {
    io::CalibrationUncertainty& u = config.nominal_uncertainty;
    const Eigen::Vector3d rotation_deg = Eigen::Vector3d::Constant(np.rotation_deg);
    const Eigen::Vector3d translation_m = Eigen::Vector3d::Constant(np.translation_m);
    u.T_I_L.sigma_rot_deg = rotation_deg;
    u.T_I_L.sigma_p_m = translation_m;
    u.T_I_V.sigma_rot_deg = np.q_I_V ? Eigen::Vector3d::Constant(np.q_I_V_sigma_deg) : rotation_deg;
    u.T_I_V.sigma_p_m = translation_m;
    u.p_I_A_m.sigma = translation_m;
    u.time_offset_lidar_imu_s.sigma = np.time_offset_s;
    u.wheel_radius_left_m.sigma = np.wheel_radius_sigma_m;
    u.wheel_radius_right_m.sigma = np.wheel_radius_sigma_m;
    u.track_width_m.sigma = np.track_width_sigma_m;
  }
  return config;
}

int64_t Simulator::StampAt(double t_s) const { return options_.start_time_ns + SecondsToNs(t_s); }

double Simulator::TimeOf(int64_t t_ns) const {
  return SecondsBetween(options_.start_time_ns, t_ns);
}

geometry::Pose3d Simulator::ImuPoseAt(double t_s) const {
  return scenario_.trajectory->PoseAt(t_s) * T_V_I_;
}

ImuLog Simulator::GenerateImu() const {
  const ImuSimOptions& o = options_.imu;
  const double rate = o.noise.update_rate_hz;
  const int64_t dt_ns = SecondsToNs(1.0 / rate);
  const double dt = NsToSeconds(dt_ns);
  const int64_t n = static_cast<int64_t>(std::floor(options_.duration_s / dt)) + 1;
  const double scale = o.add_noise ? o.noise_scale : 0.0;
  // Discrete white noise sigma_d = sigma_c sqrt(rate); bias step sigma_b = sigma_bc sqrt(dt).
  const double gyro_sigma = scale * o.noise.gyroscope_noise_density * std::sqrt(1.0 / dt);
  const double accel_sigma = scale * o.noise.accelerometer_noise_density * std::sqrt(1.0 / dt);
  const double walk_scale = o.add_noise ? o.RandomWalkScale() : 0.0;
  const double gyro_walk = walk_scale * o.noise.gyroscope_random_walk * std::sqrt(dt);
  const double accel_walk = walk_scale * o.noise.accelerometer_random_walk * std::sqrt(dt);
  std::mt19937_64 rng = RandomStream(options_.seed, Stream::kImu);
  std::normal_distribution<double> normal(0.0, 1.0);
  auto draw = [&](double sigma) -> Eigen::Vector3d {
    return DrawVector3([&] { return normal(rng); }) * sigma;
  };
  const double bias_scale = o.add_noise ? 1.0 : 0.0;
  Eigen::Vector3d b_g = draw(bias_scale * o.initial_gyro_bias_sigma_rad_s);
  Eigen::Vector3d b_a = draw(bias_scale * o.initial_accel_bias_sigma_m_s2);
  const Eigen::Vector3d g_W(0.0, 0.0, -o.gravity_m_s2);

  StampJitter jitter(o.stamp_jitter_s, options_.seed, Stream::kImuStamps);
  const int64_t end_ns = SecondsToNs(options_.duration_s);

  ImuLog log;
  log.samples.reserve(n);
  log.gyro_bias.reserve(n);
  log.accel_bias.reserve(n);
  log.truth.reserve(n);
  for (int64_t k = 0; k < n; ++k) {
    const int64_t t_ns = options_.start_time_ns + JitteredInstant(k, dt_ns, end_ns, &jitter);
    const BodyState state = scenario_.trajectory->StateAt(TimeOf(t_ns), T_V_I_);
    sensors::ImuSample sample;
    sample.t_ns = t_ns;
    sample.gyro_rad_s = state.omega_B + b_g + draw(gyro_sigma);
    // Specific force: f_I = R_W_I^T (a_W - g_W).
    sample.accel_m_s2 = state.T_W_B.q.conjugate() * (state.a_W - g_W) + b_a + draw(accel_sigma);
    log.samples.push_back(sample);
    log.gyro_bias.push_back(b_g);
    log.accel_bias.push_back(b_a);
    log.truth.push_back({t_ns, state.T_W_B, state.v_W});
    b_g += draw(gyro_walk);
    b_a += draw(accel_walk);
  }
  return log;
}

WheelLog Simulator::GenerateWheelLog() const {
  WheelLog log;
  if (!options_.wheel.enabled) return log;
  const WheelSimOptions& o = options_.wheel;
  const sensors::Calibration& truth = options_.true_calibration;
  const int64_t dt_ns = SecondsToNs(1.0 / o.config.rate_hz);
  const int64_t n = static_cast<int64_t>(std::floor(options_.duration_s / NsToSeconds(dt_ns))) + 1;
  std::mt19937_64 rng = RandomStream(options_.seed, Stream::kWheel);
  std::normal_distribution<double> noise(0.0, o.add_noise ? o.config.noise_rad_s : 0.0);
  // The stamp stream gives the jitter of every instant first, then the losses.
  StampJitter jitter(o.stamp_jitter_s, options_.seed, Stream::kWheelStamps);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  // Measurement instants in trajectory time (IMU clock), and when each sample arrives.
  const int64_t end_ns = SecondsToNs(options_.duration_s);
  std::vector<int64_t> instants(n);
  for (int64_t k = 0; k < n; ++k) instants[k] = JitteredInstant(k, dt_ns, end_ns, &jitter);
  const std::vector<int64_t> arrivals = ArrivalTimes(instants, o.burst_size, o.burst_span_s);
  const int64_t offset_ns = SecondsToNs(o.time_offset_wheel_imu_s);
  log.samples.reserve(n);
  for (int64_t k = 0; k < n; ++k) {
    const BodyState v_state = scenario_.trajectory->StateAt(NsToSeconds(instants[k]));
    // V's origin: forward speed and yaw rate in V; wheel contact speeds v -+ omega b / 2
    // (left, right), rates over the true radii.
    const double forward = (v_state.T_W_B.q.conjugate() * v_state.v_W).x();
    const double yaw_rate = v_state.omega_B.z();
    const double half_track = 0.5 * truth.track_width_m;
    sensors::WheelSample sample;
    // Stamped on the wheel clock: t_wheel = t_imu - offset.
    sample.t_ns = options_.start_time_ns + arrivals[k] - offset_ns;
    sample.left_rad_s = (forward - yaw_rate * half_track) / truth.wheel_radius_left_m + noise(rng);
    sample.right_rad_s =
        (forward + yaw_rate * half_track) / truth.wheel_radius_right_m + noise(rng);
    if (o.drop_probability > 0.0 && uniform(jitter.rng()) < o.drop_probability) continue;
    log.samples.push_back(sample);
    log.true_t_ns.push_back(options_.start_time_ns + instants[k]);
    log.speed_m_s.push_back(forward);
    log.yaw_rate_rad_s.push_back(yaw_rate);
  }
  return log;
}

sensors::WheelSpeedSamples Simulator::WheelSpeedsOf(const WheelLog& log) const {
  const sensors::Calibration& truth = options_.true_calibration;
  std::mt19937_64 rng = RandomStream(options_.seed, Stream::kWheelForm);
  const WheelSimOptions& o = options_.wheel;
  std::normal_distribution<double> noise(0.0, o.add_noise ? o.config.noise_m_s : 0.0);
  const double half_track = 0.5 * truth.track_width_m;
  sensors::WheelSpeedSamples out(log.samples.size());
  for (size_t k = 0; k < out.size(); ++k) {
    // The true contact speed v -+ omega b / 2 is the scale times the reported one.
    const double v = log.speed_m_s[k], omega = log.yaw_rate_rad_s[k];
    out[k].t_ns = log.samples[k].t_ns;
    out[k].left_m_s = (v - omega * half_track) / truth.wheel_speed_scale_left + noise(rng);
    out[k].right_m_s = (v + omega * half_track) / truth.wheel_speed_scale_right + noise(rng);
  }
  return out;
}

sensors::OdometrySamples Simulator::OdometryOf(const WheelLog& log) const {
  const sensors::Calibration& truth = options_.true_calibration;
  const WheelSimOptions& o = options_.wheel;
  std::mt19937_64 rng = RandomStream(options_.seed, Stream::kWheelForm);
  std::normal_distribution<double> speed_noise(0.0, o.add_noise ? o.config.noise_m_s : 0.0);
  std::normal_distribution<double> yaw_noise(0.0,
                                             o.add_noise ? o.config.yaw_rate_noise_rad_s : 0.0);
  const double k_v = truth.odometry_speed_scale;
  const double b_ctrl = o.config.controller_track_m.value_or(nominal_.effective_track_m);
  sensors::OdometrySamples out(log.samples.size());
  for (size_t k = 0; k < out.size(); ++k) {
    // Eq. F26 inverted: v = k_v v_odo, omega = k_v w_odo b_ctrl / b_eff.
    out[k].t_ns = log.samples[k].t_ns;
    out[k].speed_m_s = log.speed_m_s[k] / k_v + speed_noise(rng);
    out[k].yaw_rate_rad_s =
        log.yaw_rate_rad_s[k] * truth.effective_track_m / (k_v * b_ctrl) + yaw_noise(rng);
  }
  return out;
}

GnssLog Simulator::GenerateGnss() const {
  GnssLog log;
  if (!options_.gnss.enabled) return log;
  const GnssSimOptions& o = options_.gnss;
  std::mt19937_64 rng = RandomStream(options_.seed, Stream::kGnss);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double duration = options_.duration_s;
  for (int i = 0; i < o.num_outages; ++i) {
    const double span = std::max(0.0, 0.8 * duration - o.outage_duration_s);
    const double begin = 0.1 * duration + span * uniform(rng);
    log.outages_s.emplace_back(begin, begin + o.outage_duration_s);
  }
  std::sort(log.outages_s.begin(), log.outages_s.end());
  // The reported sigma drifts slowly between 1x and 2x the configured one.
  const double sigma_phase = 2.0 * M_PI * uniform(rng);
  const double sigma_period_s = 20.0 + 20.0 * uniform(rng);

  const GeographicLib::LocalCartesian enu(o.origin_lat_deg, o.origin_lon_deg, o.origin_alt_m);
  const int64_t dt_ns = SecondsToNs(1.0 / o.config.rate_hz);
  const int64_t n = static_cast<int64_t>(std::floor(duration / NsToSeconds(dt_ns))) + 1;
  const double noise_on = o.add_noise ? 1.0 : 0.0;
  const int64_t offset_ns = SecondsToNs(o.time_offset_gnss_imu_s);
  const double a = o.error_correlation_time_s > 0.0
                       ? std::exp(-NsToSeconds(dt_ns) / o.error_correlation_time_s)
                       : 0.0;
  Eigen::Vector3d unit_error = Eigen::Vector3d::Zero();
  for (int64_t k = 0; k < n; ++k) {
    // Measured at IMU time t, stamped t - offset on the receiver's clock.
    const int64_t t_ns = options_.start_time_ns + k * dt_ns;
    const double t = TimeOf(t_ns);
    // Draw every random number of the epoch even when it falls in an outage, so that an
    // outage does not shift the noise of the fixes after it.
    const Eigen::Vector3d unit_noise = DrawVector3([&] { return normal(rng); });
    unit_error =
        k == 0 ? unit_noise : Eigen::Vector3d(a * unit_error + std::sqrt(1.0 - a * a) * unit_noise);
    const bool outlier = uniform(rng) < o.outlier_probability;
    const double outlier_angle = 2.0 * M_PI * uniform(rng);
    const double outlier_horizontal = 3.0 + 12.0 * uniform(rng);
    const double outlier_vertical = -5.0 + 10.0 * uniform(rng);
    const bool in_outage = std::any_of(log.outages_s.begin(), log.outages_s.end(),
                                       [t](const auto& o) { return t >= o.first && t < o.second; });
    if (in_outage) continue;
    const double sigma_scale = 1.5 + 0.5 * std::sin(2.0 * M_PI * t / sigma_period_s + sigma_phase);
    const Eigen::Vector3d sigma = sigma_scale * o.std_enu_m;
    const Eigen::Vector3d p_W_A = ImuPoseAt(t) * options_.true_calibration.p_I_A;
    Eigen::Vector3d measured = p_W_A + noise_on * sigma.cwiseProduct(unit_error);
    if (outlier) {
      measured += Eigen::Vector3d(outlier_horizontal * std::cos(outlier_angle),
                                  outlier_horizontal * std::sin(outlier_angle), outlier_vertical);
    }
    sensors::GnssFix fix;
    fix.t_ns = t_ns - offset_ns;
    enu.Reverse(measured.x(), measured.y(), measured.z(), fix.lat_deg, fix.lon_deg, fix.alt_m);
    fix.std_enu_m = sigma;
    log.fixes.push_back(fix);
    log.is_outlier.push_back(outlier);
    log.true_p_W_A.push_back(p_W_A);
  }
  return log;
}

int64_t Simulator::SweepStamp(int index) const {
  return first_sweep_stamp_ns_ + index * SecondsToNs(1.0 / options_.lidar.config.rate_hz);
}

double Simulator::ColumnTime(int column) const {
  return column / (options_.lidar.config.rate_hz * num_columns_);
}

Eigen::Vector3d Simulator::BeamDirection(int beam, int column) const {
  return beam_directions_[static_cast<size_t>(column) * options_.lidar.config.num_beams + beam];
}

lidar::LidarSweep Simulator::GenerateSweep(int index) const {
  if (index < 0 || index >= num_sweeps_) {
    throw Error("simulated LiDAR: sweep " + std::to_string(index) + " out of range [0, " +
                std::to_string(num_sweeps_) + ")");
  }
  const LidarSimOptions& o = options_.lidar;
  const sensors::LidarConfig& l = o.config;
  lidar::LidarSweep sweep;
  const int64_t start_ns = SweepStamp(index);
  const int64_t period_ns = SecondsToNs(1.0 / l.rate_hz);
  sweep.t_ns = o.stamp_at_end ? start_ns + period_ns : start_ns;
  const double stamp_after_start_s = NsToSeconds(sweep.t_ns - start_ns);
  // IMU time of the sweep's first column: t_imu = t_lidar + offset.
  const double t0 = TimeOf(start_ns) + options_.true_calibration.time_offset_lidar_imu_s;
  const double period = 1.0 / l.rate_hz;
  const VehicleTrajectory& trajectory = *scenario_.trajectory;
  SweepRaycaster raycaster(*scenario_.world, (trajectory.PoseAt(t0) * T_V_L_).p,
                           (trajectory.PoseAt(t0 + period) * T_V_L_).p, t0, t0 + period,
                           l.max_range_m);
  std::mt19937_64 rng = RandomStream(options_.seed, Stream::kLidar, index);
  std::normal_distribution<double> range_noise(0.0, o.add_noise ? l.range_noise_m : 0.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);

  std::vector<Eigen::Vector3d> points;
  std::vector<float> intensity;
  std::vector<double> time_s;
  const size_t expected = static_cast<size_t>(num_columns_) * l.num_beams / 2;
  points.reserve(expected);
  intensity.reserve(expected);
  time_s.reserve(expected);
  RayHit hit;
  for (int c = 0; c < num_columns_; ++c) {
    const double tau = ColumnTime(c);
    const geometry::Pose3d T_W_L = trajectory.PoseAt(t0 + tau) * T_V_L_;
    const Eigen::Matrix3d R_W_L = T_W_L.R();
    raycaster.SetTime(t0 + tau);
    for (int b = 0; b < l.num_beams; ++b) {
      const Eigen::Vector3d d_L = BeamDirection(b, c);
      const Eigen::Vector3d d_W = R_W_L * d_L;
      const double noise = range_noise(rng);
      const bool dropped = uniform(rng) < o.dropout_probability;
      if (!raycaster.Raycast(T_W_L.p, d_W, l.min_range_m, l.max_range_m, &hit) || dropped) {
        continue;
      }
      const double range = hit.range_m + noise;
      if (range < l.min_range_m || range > l.max_range_m) continue;
      points.push_back(range * d_L);
      // Lambertian return: reflectivity times the cosine of the incidence angle.
      intensity.push_back(
          static_cast<float>(255.0 * hit.reflectivity * std::abs(hit.normal_W.dot(d_W))));
      time_s.push_back(tau - stamp_after_start_s);
    }
  }
  const Eigen::Index n = static_cast<Eigen::Index>(points.size());
  sweep.cloud.points.resize(3, n);
  sweep.cloud.intensity.resize(n);
  sweep.cloud.time_s.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    sweep.cloud.points.col(i) = points[i];
    sweep.cloud.intensity(i) = intensity[i];
    sweep.cloud.time_s(i) = time_s[i];
  }
  return sweep;
}

SimulatedLog Simulate(const Simulator& simulator) {
  SimulatedLog log;
  log.imu = simulator.GenerateImu();
  log.wheel = simulator.GenerateWheel();
  log.gnss = simulator.GenerateGnss();
  log.sweeps.reserve(simulator.num_sweeps());
  for (int k = 0; k < simulator.num_sweeps(); ++k) log.sweeps.push_back(simulator.GenerateSweep(k));
  return log;
}

SimulatedLog Simulate(const SimulationOptions& options) { return Simulate(Simulator(options)); }

}  // namespace sim
}  // namespace autocal
