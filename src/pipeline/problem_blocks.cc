#include "problem_blocks.h"

#include <optional>
#include <utility>

#include "autocal/common/units.h"
#include "calibration_steps.h"

namespace autocal {
namespace pipeline {

namespace {

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

}  // namespace

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
    b.max_kept_sigma_to_limit = o.max_kept_sigma_to_limit;
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


}  // namespace pipeline
}  // namespace autocal
