// autocal_simulate: writes a simulated drive (IMU, LiDAR, wheels, GNSS, ground truth) as an
// autocal dataset and prints a summary of it. See docs/simulator.md.

#include <gflags/gflags.h>

#include <cstdio>
#include <exception>
#include <string>

#include "autocal/common/error.h"
#include "autocal/io/output_files.h"
#include "autocal/sim/simulator.h"
#include "tool_help.h"

DEFINE_string(scenario, "urban",
              "urban (<= 50 km/h, turns, stops, a roundabout, grades) or highway (~120 km/h, "
              "curves, lane changes, a lead vehicle)");
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
DEFINE_double(gnss_rate_hz, 10.0, "GNSS fix rate: 10 or 1 Hz");
DEFINE_int32(gnss_outages, 2, "number of GNSS outages");
DEFINE_double(gnss_outage_s, 4.0, "length of each GNSS outage, seconds");
DEFINE_double(gnss_outlier_probability, 0.02, "probability that a fix is a multipath outlier");
DEFINE_double(origin_lat_deg, 49.0110, "latitude of the world origin, degrees (WGS84)");
DEFINE_double(origin_lon_deg, 8.4170, "longitude of the world origin, degrees (WGS84)");
DEFINE_double(origin_alt_m, 165.0, "ellipsoidal height of the world origin, metres");
DEFINE_double(imu_rate_hz, 200.0, "IMU sample rate, Hz");
DEFINE_double(imu_noise_scale, 1.0,
              "scale of the IMU noise densities and random walks (EuRoC-class MEMS at 1)");
DEFINE_double(wheel_rate_hz, 100.0, "wheel encoder rate, Hz");
DEFINE_double(wheel_noise_rad_s, 0.02, "wheel rate noise, 1-sigma rad/s");
DEFINE_bool(noise, true, "false: every sensor exact (no noise, bias, dropouts or outliers)");

namespace {

autocal::sim::SimulationOptions OptionsFromFlags() {
  using autocal::Error;
  autocal::sim::SimulationOptions o;
  o.scenario = autocal::sim::ParseScenarioType(FLAGS_scenario);
  o.duration_s = FLAGS_duration_s;
  o.seed = FLAGS_seed;
  auto& lidar = o.lidar.config;
  lidar.num_beams = FLAGS_lidar_beams;
  switch (FLAGS_lidar_beams) {
    case 16:
      lidar.min_elevation_deg = -15.0;
      lidar.max_elevation_deg = 15.0;
      break;
    case 32:
      lidar.min_elevation_deg = -25.0;
      lidar.max_elevation_deg = 15.0;
      break;
    case 64:
      lidar.min_elevation_deg = -24.8;
      lidar.max_elevation_deg = 2.0;
      break;
    default:
      throw Error("--lidar_beams must be 16, 32 or 64, got " + std::to_string(FLAGS_lidar_beams));
  }
  lidar.rate_hz = FLAGS_lidar_rate_hz;
  lidar.azimuth_resolution_deg = FLAGS_lidar_azimuth_resolution_deg;
  lidar.max_range_m = FLAGS_lidar_max_range_m;
  lidar.range_noise_m = FLAGS_lidar_range_noise_m;
  o.lidar.dropout_probability = FLAGS_lidar_dropout;
  o.lidar.enabled = FLAGS_lidar;
  if (FLAGS_gnss_rate_hz != 10.0 && FLAGS_gnss_rate_hz != 1.0) {
    throw Error("--gnss_rate_hz must be 10 or 1, got " + std::to_string(FLAGS_gnss_rate_hz));
  }
  o.gnss.config.rate_hz = FLAGS_gnss_rate_hz;
  o.gnss.num_outages = FLAGS_gnss_outages;
  o.gnss.outage_duration_s = FLAGS_gnss_outage_s;
  o.gnss.outlier_probability = FLAGS_gnss_outlier_probability;
  o.gnss.origin_lat_deg = FLAGS_origin_lat_deg;
  o.gnss.origin_lon_deg = FLAGS_origin_lon_deg;
  o.gnss.origin_alt_m = FLAGS_origin_alt_m;
  o.imu.noise.update_rate_hz = FLAGS_imu_rate_hz;
  o.imu.noise_scale = FLAGS_imu_noise_scale;
  o.wheel.config.rate_hz = FLAGS_wheel_rate_hz;
  o.wheel.config.noise_rad_s = FLAGS_wheel_noise_rad_s;
  return FLAGS_noise ? o : o.WithoutNoise();
}

}  // namespace

int main(int argc, char** argv) {
  gflags::SetUsageMessage(
      "writes a simulated drive as an autocal dataset and prints its summary\n"
      "  autocal_simulate --scenario=urban|highway --duration_s=60 --seed=1 --out=DIR\n"
      "Output: sensors.yaml (nominal calibration = truth perturbed), imu.csv, wheel.csv,\n"
      "gnss.csv, lidar.csv + lidar/*.ply, groundtruth/{trajectory.csv, calibration.yaml,\n"
      "imu_bias.csv, gnss.csv}. Same seed, same dataset.");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_simulate")) return 0;
  gflags::ParseCommandLineFlags(&argc, &argv, true);
  try {
    if (argc > 1) throw autocal::Error(std::string("unexpected argument '") + argv[1] + "'");
    if (FLAGS_out.empty()) throw autocal::Error("--out=DIR is required");
    autocal::io::CheckOutputDirectory(FLAGS_out, autocal::io::OutputKind::kDataset);
    const autocal::sim::Simulator simulator(OptionsFromFlags());
    const autocal::sim::SimulationSummary summary =
        autocal::sim::WriteDataset(simulator, FLAGS_out);
    std::printf("wrote %s\n%s", FLAGS_out.c_str(), autocal::sim::FormatSummary(summary).c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "autocal_simulate: %s\n", e.what());
    return 1;
  }
  return 0;
}
