#include "autocal/io/sensors_yaml.h"

#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "io/calibration_node.h"
#include "io/text_format.h"
#include "io/yaml_util.h"

namespace autocal {
namespace io {
namespace {

using internal::YamlFile;

// Gravity on Earth's surface varies between 9.78 and 9.84 m/s^2; a value outside this
// band is a unit or typing mistake.
constexpr double kMinGravity = 9.7;
constexpr double kMaxGravity = 9.9;

sensors::ImuConfig ParseImu(const YamlFile& file, const YAML::Node& node) {
  file.ExpectMap(node, "imu",
                 {"gyroscope_noise_density", "gyroscope_random_walk", "accelerometer_noise_density",
                  "accelerometer_random_walk", "update_rate", "gravity_m_s2", "rostopic"});
  sensors::ImuConfig imu;
  sensors::ImuNoise& noise = imu.noise;
  const auto required = [&](const char* key, double min_value, double max_value, const char* unit) {
    return file.DoubleInRange(file.Required(node, "imu", key), std::string("imu.") + key, min_value,
                              max_value, unit);
  };
  noise.gyroscope_noise_density = required("gyroscope_noise_density", 1e-7, 1.0, "rad/s/sqrt(Hz)");
  noise.gyroscope_random_walk = required("gyroscope_random_walk", 1e-9, 1.0, "rad/s^2/sqrt(Hz)");
  noise.accelerometer_noise_density =
      required("accelerometer_noise_density", 1e-6, 10.0, "m/s^2/sqrt(Hz)");
  noise.accelerometer_random_walk =
      required("accelerometer_random_walk", 1e-8, 10.0, "m/s^3/sqrt(Hz)");
  noise.update_rate_hz = required("update_rate", kImuRateRangeHz.min, kImuRateRangeHz.max, "Hz");
  if (const YAML::Node gravity = node["gravity_m_s2"]) {
    imu.gravity_m_s2 = file.Double(gravity, "imu.gravity_m_s2");
    if (imu.gravity_m_s2 < kMinGravity || imu.gravity_m_s2 > kMaxGravity) {
      file.Fail(gravity, "imu.gravity_m_s2: " + gravity.Scalar() +
                             " is not Earth's gravity in m/s^2 (expected 9.7 to 9.9)");
    }
  }
  if (node["rostopic"]) file.String(node["rostopic"], "imu.rostopic");
  return imu;
}

sensors::LidarConfig ParseLidar(const YamlFile& file, const YAML::Node& node) {
  file.ExpectMap(node, "lidar",
                 {"num_beams", "rate_hz", "min_elevation_deg", "max_elevation_deg",
                  "azimuth_resolution_deg", "min_range_m", "max_range_m", "range_noise_m"});
  sensors::LidarConfig lidar;
  if (const YAML::Node n = node["num_beams"]) {
    const int64_t beams = file.Int(n, "lidar.num_beams");
    if (beams < 1 || beams > 1024) file.Fail(n, "lidar.num_beams: must be within [1, 1024]");
    lidar.num_beams = static_cast<int>(beams);
  }
  if (const YAML::Node n = node["rate_hz"])
    lidar.rate_hz =
        file.DoubleInRange(n, "lidar.rate_hz", kLidarRateRangeHz.min, kLidarRateRangeHz.max, "Hz");
  if (const YAML::Node n = node["min_elevation_deg"])
    lidar.min_elevation_deg = file.Double(n, "lidar.min_elevation_deg");
  if (const YAML::Node n = node["max_elevation_deg"])
    lidar.max_elevation_deg = file.Double(n, "lidar.max_elevation_deg");
  if (const YAML::Node n = node["azimuth_resolution_deg"]) {
    lidar.azimuth_resolution_deg =
        file.DoubleInRange(n, "lidar.azimuth_resolution_deg", 0.001, 360.0, "deg");
  }
  if (const YAML::Node n = node["min_range_m"])
    lidar.min_range_m = file.DoubleInRange(n, "lidar.min_range_m", 0.0, 1000.0, "m");
  if (const YAML::Node n = node["max_range_m"])
    lidar.max_range_m = file.DoubleInRange(n, "lidar.max_range_m", 0.1, 10000.0, "m");
  if (const YAML::Node n = node["range_noise_m"])
    lidar.range_noise_m = file.DoubleInRange(n, "lidar.range_noise_m", 0.0, 10.0, "m");
  if (!(lidar.min_elevation_deg < lidar.max_elevation_deg) || lidar.min_elevation_deg < -90.0 ||
      lidar.max_elevation_deg > 90.0) {
    file.Fail(node, "lidar: need -90 <= min_elevation_deg < max_elevation_deg <= 90");
  }
  if (!(lidar.min_range_m >= 0.0 && lidar.min_range_m < lidar.max_range_m)) {
    file.Fail(node, "lidar: need 0 <= min_range_m < max_range_m");
  }
  if (lidar.range_noise_m < 0.0)
    file.Fail(node["range_noise_m"], "lidar.range_noise_m: must be >= 0");
  return lidar;
}

sensors::WheelConfig ParseWheel(const YamlFile& file, const YAML::Node& node) {
  file.ExpectMap(
      node, "wheel",
      {"form", "rate_hz", "noise_rad_s", "noise_m_s", "yaw_rate_noise_rad_s", "controller_track_m",
       "lateral_slip_sigma_m_s", "cornering_compliance_rad_per_m_s2"});
  sensors::WheelConfig wheel;
  if (const YAML::Node n = node["form"]) {
    const std::string name = file.String(n, "wheel.form");
    if (!sensors::ParseWheelForm(name, &wheel.form)) {
      file.Fail(n, "wheel.form: expected angular_rates, linear_speeds or speed_yaw_rate, found '" +
                       name + "'");
    }
  }
  if (const YAML::Node n = node["rate_hz"])
    wheel.rate_hz =
        file.DoubleInRange(n, "wheel.rate_hz", kWheelRateRangeHz.min, kWheelRateRangeHz.max, "Hz");
  if (const YAML::Node n = node["noise_rad_s"])
    wheel.noise_rad_s =
        file.DoubleInRange(n, "wheel.noise_rad_s", kMinWheelSigma, kMaxWheelSigma, "rad/s");
  if (const YAML::Node n = node["noise_m_s"])
    wheel.noise_m_s =
        file.DoubleInRange(n, "wheel.noise_m_s", kMinWheelSigma, kMaxWheelSigma, "m/s");
  if (const YAML::Node n = node["yaw_rate_noise_rad_s"]) {
    wheel.yaw_rate_noise_rad_s = file.DoubleInRange(n, "wheel.yaw_rate_noise_rad_s", kMinWheelSigma,
                                                    kMaxWheelSigma, "rad/s");
  }
  if (const YAML::Node n = node["controller_track_m"]) {
    if (wheel.form != sensors::WheelForm::kSpeedYawRate) {
      file.Fail(n,
                "wheel.controller_track_m: only the form speed_yaw_rate has a controller track "
                "(wheel.form is " +
                    std::string(sensors::WheelFormName(wheel.form)) + ")");
    }
    wheel.controller_track_m = file.DoubleInRange(n, "wheel.controller_track_m", 0.05, 100.0, "m");
  }
  if (const YAML::Node n = node["lateral_slip_sigma_m_s"]) {
    wheel.lateral_slip_sigma_m_s = file.DoubleInRange(n, "wheel.lateral_slip_sigma_m_s",
                                                      kMinWheelSigma, kMaxWheelSigma, "m/s");
  }
  if (const YAML::Node n = node["cornering_compliance_rad_per_m_s2"]) {
    wheel.cornering_compliance_rad_per_m_s2 =
        file.DoubleInRange(n, "wheel.cornering_compliance_rad_per_m_s2", 0.0, 1.0, "rad/(m/s^2)");
  }
  return wheel;
}

sensors::GnssConfig ParseGnss(const YamlFile& file, const YAML::Node& node) {
  file.ExpectMap(node, "gnss", {"rate_hz"});
  sensors::GnssConfig gnss;
  if (const YAML::Node n = node["rate_hz"])
    gnss.rate_hz =
        file.DoubleInRange(n, "gnss.rate_hz", kGnssRateRangeHz.min, kGnssRateRangeHz.max, "Hz");
  return gnss;
}

std::string Number(double value) {
  if (!std::isfinite(value)) throw Error("sensors.yaml: a sensor parameter is not finite");
  return internal::FormatDouble(value);
}

}  // namespace

SensorsConfig ReadSensorsYaml(const std::string& path) {
  const YamlFile file(path);
  const YAML::Node& root = file.root();
  file.ExpectMap(root, "sensors.yaml", {"imu", "lidar", "wheel", "gnss", "nominal_calibration"});
  SensorsConfig config;
  config.imu = ParseImu(file, file.Required(root, "sensors.yaml", "imu"));
  if (root["lidar"]) config.lidar = ParseLidar(file, root["lidar"]);
  if (root["wheel"]) config.wheel = ParseWheel(file, root["wheel"]);
  if (root["gnss"]) config.gnss = ParseGnss(file, root["gnss"]);
  if (root["nominal_calibration"]) {
    const CalibrationFile nominal =
        internal::ParseCalibrationNode(file, root["nominal_calibration"], "nominal_calibration");
    if (!nominal.solver.empty() || !nominal.residuals.empty()) {
      file.Fail(
          root["nominal_calibration"],
          "nominal_calibration: 'solver' and 'residuals' belong to results, not to sensors.yaml");
    }
    config.nominal_calibration = nominal.value;
    config.nominal_uncertainty = nominal.uncertainty;
  }
  return config;
}

void WriteSensorsYaml(const std::string& path, const SensorsConfig& config) {
  const sensors::ImuNoise& noise = config.imu.noise;
  std::string text =
      "# autocal sensors (schema: datasets/README.md)\n"
      "imu:\n"
      "  gyroscope_noise_density: " +
      Number(noise.gyroscope_noise_density) + "  # rad/s/sqrt(Hz)\n" +
      "  gyroscope_random_walk: " + Number(noise.gyroscope_random_walk) + "  # rad/s^2/sqrt(Hz)\n" +
      "  accelerometer_noise_density: " + Number(noise.accelerometer_noise_density) +
      "  # m/s^2/sqrt(Hz)\n" +
      "  accelerometer_random_walk: " + Number(noise.accelerometer_random_walk) +
      "  # m/s^3/sqrt(Hz)\n" + "  update_rate: " + Number(noise.update_rate_hz) + "  # Hz\n" +
      "  gravity_m_s2: " + Number(config.imu.gravity_m_s2) + "\n";
  if (config.lidar) {
    const sensors::LidarConfig& l = *config.lidar;
    text += "lidar:\n  num_beams: " + std::to_string(l.num_beams) +
            "\n  rate_hz: " + Number(l.rate_hz) +
            "\n  min_elevation_deg: " + Number(l.min_elevation_deg) +
            "\n  max_elevation_deg: " + Number(l.max_elevation_deg) +
            "\n  azimuth_resolution_deg: " + Number(l.azimuth_resolution_deg) +
            "\n  min_range_m: " + Number(l.min_range_m) +
            "\n  max_range_m: " + Number(l.max_range_m) +
            "\n  range_noise_m: " + Number(l.range_noise_m) + "\n";
  }
  if (config.wheel) {
    const sensors::WheelConfig& w = *config.wheel;
    text +=
        std::string("wheel:\n  form: ") + sensors::WheelFormName(w.form) +
        "\n  rate_hz: " + Number(w.rate_hz) + "\n  noise_rad_s: " + Number(w.noise_rad_s) +
        "\n  noise_m_s: " + Number(w.noise_m_s) +
        "\n  yaw_rate_noise_rad_s: " + Number(w.yaw_rate_noise_rad_s) +
        "\n  lateral_slip_sigma_m_s: " + Number(w.lateral_slip_sigma_m_s) +
        "\n  cornering_compliance_rad_per_m_s2: " + Number(w.cornering_compliance_rad_per_m_s2) +
        "\n";
    if (w.controller_track_m)
      text += "  controller_track_m: " + Number(*w.controller_track_m) + "\n";
  }
  if (config.gnss) text += "gnss:\n  rate_hz: " + Number(config.gnss->rate_hz) + "\n";
  CalibrationFile nominal;
  nominal.value = config.nominal_calibration;
  nominal.uncertainty = config.nominal_uncertainty;
  text += "nominal_calibration:\n" + CalibrationYamlText(nominal, 2);
  internal::WriteFileText(path, text);
}

}  // namespace io
}  // namespace autocal
