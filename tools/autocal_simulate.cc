// autocal_simulate: writes a simulated drive (IMU, LiDAR, wheels, GNSS, ground truth) as an
// autocal dataset and prints a summary of it. See docs/simulator.md.

#include <gflags/gflags.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>
#include <thread>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/io/output_files.h"
#include "autocal/sim/simulator.h"
#include "keep_freed_memory.h"
#include "tool_checks.h"
#include "tool_help.h"

DEFINE_string(preset, "",
              "start from a platform: skid_steer (slow robot, y-up IMU, late odometry) or "
              "can_bus_car (z-down IMU, bursty CAN wheels, late GNSS); flags given override it");
DEFINE_string(scenario, "urban",
              "urban (<= 50 km/h, turns, stops, roundabout), highway (~120 km/h), skid_steer "
              "(<= 1 m/s, pivots, loops) or straight (one heading, speed changes)");
DEFINE_double(duration_s, 60.0, "length of the drive, seconds (0 < d <= 3600)");
DEFINE_uint64(seed, 1, "random seed: drive, world, noise and the nominal calibration");
DEFINE_string(out, "",
              "output dataset directory; required. Written whole at the end (a stopped run "
              "leaves only OUT.partial-XXXXXX); an existing one is replaced only when it holds "
              "nothing but dataset files, otherwise refused");
DEFINE_int32(lidar_beams, 32,
             "LiDAR beams: 16 (-15..15 deg), 32 (-25..15 deg) or 64 (-24.8..2 deg)");
DEFINE_double(lidar_rate_hz, 10.0, "LiDAR sweeps per second");
DEFINE_double(lidar_azimuth_resolution_deg, 0.4, "LiDAR azimuth step, degrees");
DEFINE_double(lidar_max_range_m, 100.0, "LiDAR maximum range, metres");
DEFINE_double(lidar_range_noise_m, 0.02, "LiDAR range noise, 1-sigma metres");
DEFINE_double(lidar_dropout, 0.02, "probability that a LiDAR return is lost");
DEFINE_bool(lidar, true, "simulate the LiDAR (false: no lidar.csv and no sweeps)");
DEFINE_bool(lidar_stamp_at_end, false,
            "stamp each sweep when it ends, its points' times negative, as some drivers do "
            "(default: when it starts)");
DEFINE_double(gnss_rate_hz, 10.0, "GNSS fix rate, Hz (0 < r <= 100)");
DEFINE_double(gnss_time_offset_s, 0.0,
              "GNSS clock offset: a fix stamped t is the antenna at IMU time t + offset");
DEFINE_int32(gnss_outages, 2, "number of GNSS outages");
DEFINE_double(gnss_outage_s, 4.0, "length of each GNSS outage, seconds");
DEFINE_double(gnss_outlier_probability, 0.02, "probability that a fix is a multipath outlier");
DEFINE_double(gnss_error_correlation_s, 0.0,
              "correlation time of the fixes' errors, seconds (Gauss-Markov; 0: independent)");
DEFINE_double(origin_lat_deg, 49.0110, "latitude of the world origin, degrees (WGS84)");
DEFINE_double(origin_lon_deg, 8.4170, "longitude of the world origin, degrees (WGS84)");
DEFINE_double(origin_alt_m, 165.0,
              "ellipsoidal height of the world origin, metres (-1000..100000)");
DEFINE_double(imu_rate_hz, 200.0,
              "IMU sample rate, Hz (20..2000); with --preset, the preset's stamp jitter keeps its "
              "share of the sample period");
DEFINE_double(imu_stamp_jitter_s, 0.0, "IMU sample instants jitter by +-this, seconds");
DEFINE_double(imu_noise_scale, 1.0,
              "scale of the IMU noise densities and random walks (EuRoC-class MEMS at 1)");
DEFINE_double(imu_random_walk_scale, -1.0,
              "scale of the IMU bias random walks when it differs from --imu_noise_scale "
              "(vibration raises the white noise only); negative: --imu_noise_scale");
DEFINE_string(imu_mount_rpy_deg, "",
              "true IMU mount R_V_I as roll,pitch,yaw degrees (e.g. 180,0,0: z down); LiDAR "
              "and antenna stay where they are in the vehicle");
DEFINE_string(nominal_imu_mount_rpy_deg, "",
              "R_V_I written to sensors.yaml as roll,pitch,yaw degrees (default: a draw near "
              "the truth)");
DEFINE_double(wheel_rate_hz, 100.0,
              "wheel encoder rate, Hz; with --preset, the preset's stamp jitter and burst span "
              "keep their share of the sample period");
DEFINE_double(wheel_noise_rad_s, 0.02, "wheel rate noise, 1-sigma rad/s");
DEFINE_double(wheel_stamp_jitter_s, 0.0, "wheel sample instants jitter by +-this, seconds");
DEFINE_int32(wheel_burst_size, 1, "wheel samples delivered in groups of this many (1: off)");
DEFINE_double(wheel_burst_span_s, 0.002, "arrival span of one wheel burst, seconds");
DEFINE_double(wheel_drop_probability, 0.0, "probability that a wheel sample is lost");
DEFINE_double(wheel_time_offset_s, 0.0,
              "wheel clock offset: a sample stamped t was measured at IMU time t + offset");
DEFINE_string(wheel_form, "angular_rates",
              "wheel data written: angular_rates (wheel.csv), linear_speeds (wheel_speed.csv) "
              "or speed_yaw_rate (odometry.csv)");
DEFINE_double(wheel_noise_m_s, 0.02,
              "noise of each wheel speed (linear_speeds) or the odometry speed, 1-sigma m/s");
DEFINE_double(wheel_yaw_rate_noise_rad_s, 0.02, "odometry yaw rate noise, 1-sigma rad/s");
DEFINE_double(left_wheel_radius_change_pct, 0.0,
              "true left rear wheel radius this many percent above the vehicle's (tyre pressure "
              "or wear between logs of one vehicle)");
DEFINE_double(right_wheel_radius_change_pct, 0.0,
              "true right rear wheel radius this many percent above the vehicle's");
DEFINE_int32(threads, 0,
             "threads generating the LiDAR sweeps; 0: every core. The dataset is the same "
             "whatever the count");
DEFINE_bool(noise, true, "false: every sensor exact (no noise, bias, dropouts or outliers)");

namespace {

using autocal::Error;

// True when the flag was given on the command line (a preset keeps the others).
bool Given(const char* name) { return !gflags::GetCommandLineFlagInfoOrDie(name).is_default; }

Eigen::Quaterniond ParseRollPitchYaw(const std::string& text, const char* flag) {
  double r = 0.0, p = 0.0, y = 0.0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%lf,%lf,%lf%c", &r, &p, &y, &tail) != 3 || !std::isfinite(r) ||
      !std::isfinite(p) || !std::isfinite(y)) {
    throw Error(std::string("--") + flag + " must be roll,pitch,yaw in degrees, got '" + text +
                "'");
  }
  return autocal::sim::RotationFromRollPitchYawDeg(r, p, y);
}

autocal::sim::SimulationOptions PresetFromFlag() {
  if (FLAGS_preset.empty()) return {};
  if (FLAGS_preset == "skid_steer") return autocal::sim::SkidSteerRobotOptions();
  if (FLAGS_preset == "can_bus_car") return autocal::sim::CanBusCarOptions();
  throw Error("--preset must be skid_steer or can_bus_car, got '" + FLAGS_preset + "'");
}

void SetLidar(autocal::sim::SimulationOptions* o, bool all) {
  auto& lidar = o->lidar.config;
  if (all || Given("lidar_beams")) {
    try {
      autocal::sim::SetSpinningLidarBeams(FLAGS_lidar_beams, &lidar);
    } catch (const Error& e) {
      throw Error(std::string("--lidar_beams: ") + e.what());
    }
  }
  auto set = [all](const char* name, auto value, auto* field) {
    if (all || Given(name)) *field = value;
  };
  set("lidar_rate_hz", FLAGS_lidar_rate_hz, &lidar.rate_hz);
  set("lidar_azimuth_resolution_deg", FLAGS_lidar_azimuth_resolution_deg,
      &lidar.azimuth_resolution_deg);
  set("lidar_max_range_m", FLAGS_lidar_max_range_m, &lidar.max_range_m);
  set("lidar_range_noise_m", FLAGS_lidar_range_noise_m, &lidar.range_noise_m);
  set("lidar_dropout", FLAGS_lidar_dropout, &o->lidar.dropout_probability);
  set("lidar", FLAGS_lidar, &o->lidar.enabled);
  set("lidar_stamp_at_end", FLAGS_lidar_stamp_at_end, &o->lidar.stamp_at_end);
}

// The options of the preset (or the defaults), then every flag given; without a preset every
// flag applies (their defaults are the options' defaults).
// --threads: 0 is every core.
int ThreadsFromFlag() {
  if (FLAGS_threads < 0 || FLAGS_threads > autocal::tools::kMaxThreads) {
    throw autocal::Error("--threads must be 0 (every core) or 1.." +
                         std::to_string(autocal::tools::kMaxThreads) + ", got " +
                         std::to_string(FLAGS_threads));
  }
  if (FLAGS_threads > 0) return FLAGS_threads;
  return std::max(1u, std::thread::hardware_concurrency());
}

// A preset's stamp jitter and burst span are shares of its sensors' sample periods: a rate
// given without them keeps those shares (a 30 Hz preset's 2 ms jitter is 0.3 ms at 200 Hz).
void KeepPresetTiming(double preset_imu_rate_hz, double preset_wheel_rate_hz,
                      autocal::sim::SimulationOptions* o) {
  const double imu = preset_imu_rate_hz / o->imu.noise.update_rate_hz;
  const double wheel = preset_wheel_rate_hz / o->wheel.config.rate_hz;
  if (!Given("imu_stamp_jitter_s")) o->imu.stamp_jitter_s *= imu;
  if (!Given("wheel_stamp_jitter_s")) o->wheel.stamp_jitter_s *= wheel;
  if (!Given("wheel_burst_span_s")) o->wheel.burst_span_s *= wheel;
}

autocal::sim::SimulationOptions OptionsFromFlags() {
  autocal::sim::SimulationOptions o = PresetFromFlag();
  const bool all = FLAGS_preset.empty();
  auto set = [all](const char* name, auto value, auto* field) {
    if (all || Given(name)) *field = value;
  };
  if (all || Given("scenario")) o.scenario = autocal::sim::ParseScenarioType(FLAGS_scenario);
  if (o.scenario == autocal::sim::ScenarioType::kSkidSteer) {
    autocal::sim::StateSkidSteerSlip(&o.wheel.config);
  }
  set("duration_s", FLAGS_duration_s, &o.duration_s);
  o.seed = FLAGS_seed;
  SetLidar(&o, all);
  set("gnss_rate_hz", FLAGS_gnss_rate_hz, &o.gnss.config.rate_hz);
  set("gnss_time_offset_s", FLAGS_gnss_time_offset_s, &o.gnss.time_offset_gnss_imu_s);
  set("gnss_outages", FLAGS_gnss_outages, &o.gnss.num_outages);
  set("gnss_outage_s", FLAGS_gnss_outage_s, &o.gnss.outage_duration_s);
  set("gnss_outlier_probability", FLAGS_gnss_outlier_probability, &o.gnss.outlier_probability);
  set("gnss_error_correlation_s", FLAGS_gnss_error_correlation_s, &o.gnss.error_correlation_time_s);
  set("origin_lat_deg", FLAGS_origin_lat_deg, &o.gnss.origin_lat_deg);
  set("origin_lon_deg", FLAGS_origin_lon_deg, &o.gnss.origin_lon_deg);
  set("origin_alt_m", FLAGS_origin_alt_m, &o.gnss.origin_alt_m);
  const double preset_imu_rate_hz = o.imu.noise.update_rate_hz;
  set("imu_rate_hz", FLAGS_imu_rate_hz, &o.imu.noise.update_rate_hz);
  set("imu_stamp_jitter_s", FLAGS_imu_stamp_jitter_s, &o.imu.stamp_jitter_s);
  set("imu_noise_scale", FLAGS_imu_noise_scale, &o.imu.noise_scale);
  if (!std::isfinite(FLAGS_imu_random_walk_scale)) {
    throw Error("--imu_random_walk_scale must be a number (negative: --imu_noise_scale), got " +
                autocal::FormatShort(FLAGS_imu_random_walk_scale));
  }
  if (FLAGS_imu_random_walk_scale >= 0.0) o.imu.random_walk_scale = FLAGS_imu_random_walk_scale;
  if (!FLAGS_imu_mount_rpy_deg.empty()) {
    o.true_calibration = autocal::sim::WithImuMount(
        o.true_calibration, ParseRollPitchYaw(FLAGS_imu_mount_rpy_deg, "imu_mount_rpy_deg"));
  }
  if (!FLAGS_nominal_imu_mount_rpy_deg.empty()) {
    o.nominal_perturbation.q_I_V =
        ParseRollPitchYaw(FLAGS_nominal_imu_mount_rpy_deg, "nominal_imu_mount_rpy_deg").conjugate();
  }
  o.true_calibration.wheel_radius_left_m *= 1.0 + FLAGS_left_wheel_radius_change_pct / 100.0;
  o.true_calibration.wheel_radius_right_m *= 1.0 + FLAGS_right_wheel_radius_change_pct / 100.0;
  const double preset_wheel_rate_hz = o.wheel.config.rate_hz;
  set("wheel_rate_hz", FLAGS_wheel_rate_hz, &o.wheel.config.rate_hz);
  set("wheel_noise_rad_s", FLAGS_wheel_noise_rad_s, &o.wheel.config.noise_rad_s);
  set("wheel_stamp_jitter_s", FLAGS_wheel_stamp_jitter_s, &o.wheel.stamp_jitter_s);
  set("wheel_burst_size", FLAGS_wheel_burst_size, &o.wheel.burst_size);
  set("wheel_burst_span_s", FLAGS_wheel_burst_span_s, &o.wheel.burst_span_s);
  set("wheel_drop_probability", FLAGS_wheel_drop_probability, &o.wheel.drop_probability);
  set("wheel_time_offset_s", FLAGS_wheel_time_offset_s, &o.wheel.time_offset_wheel_imu_s);
  if ((all || Given("wheel_form")) &&
      !autocal::sensors::ParseWheelForm(FLAGS_wheel_form, &o.wheel.config.form)) {
    throw Error("--wheel_form must be angular_rates, linear_speeds or speed_yaw_rate, got '" +
                FLAGS_wheel_form + "'");
  }
  set("wheel_noise_m_s", FLAGS_wheel_noise_m_s, &o.wheel.config.noise_m_s);
  set("wheel_yaw_rate_noise_rad_s", FLAGS_wheel_yaw_rate_noise_rad_s,
      &o.wheel.config.yaw_rate_noise_rad_s);
  if (!all) KeepPresetTiming(preset_imu_rate_hz, preset_wheel_rate_hz, &o);
  return FLAGS_noise ? o : o.WithoutNoise();
}

}  // namespace

int main(int argc, char** argv) {
  autocal::tools::StartWithHugePageHeap(argv);
  gflags::SetUsageMessage(
      "writes a simulated drive as an autocal dataset and prints its summary\n"
      "  autocal_simulate --scenario=urban|highway|skid_steer|straight --duration_s=60 "
      "--seed=1 --out=DIR\n"
      "  autocal_simulate --preset=skid_steer|can_bus_car --out=DIR\n"
      "Output: sensors.yaml (nominal calibration = truth perturbed), imu.csv, wheel.csv\n"
      "(or wheel_speed.csv, odometry.csv: --wheel_form),\n"
      "gnss.csv, lidar.csv + lidar/*.ply, groundtruth/{trajectory.csv, calibration.yaml,\n"
      "imu_bias.csv, gnss.csv, timing.yaml}. Same seed, same dataset.");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_simulate")) return 0;
  gflags::ParseCommandLineFlags(&argc, &argv, true);
  autocal::tools::KeepFreedMemory();
  try {
    if (argc > 1) throw autocal::Error(std::string("unexpected argument '") + argv[1] + "'");
    if (FLAGS_out.empty()) throw autocal::Error("--out=DIR is required");
    autocal::io::CheckOutputDirectory(FLAGS_out, autocal::io::OutputKind::kDataset);
    const autocal::sim::Simulator simulator(OptionsFromFlags());
    const autocal::sim::SimulationSummary summary =
        autocal::sim::WriteDataset(simulator, FLAGS_out, ThreadsFromFlag());
    std::printf("wrote %s\n%s", FLAGS_out.c_str(), autocal::sim::FormatSummary(summary).c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autocal_simulate: %s\n", e.what());
    return 1;
  }
  return 0;
}
