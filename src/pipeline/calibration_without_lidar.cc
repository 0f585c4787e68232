#include "calibration_steps.h"

#include <algorithm>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/estimation/gnss_inertial_keyframes.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/geometry/manifolds.h"
#include "problem_blocks.h"

namespace autocal {
namespace pipeline {

OfflineCalibrationResult CalibrateWithoutLidar(const io::Dataset& dataset,
                                               const io::Problem& problem,
                                               const OfflineCalibrationOptions& options,
                                               std::chrono::steady_clock::time_point start) {
  if (!problem.sensors.gnss || dataset.gnss.empty()) {
    throw Error("problem " + problem.path +
                ": a calibration without the LiDAR needs GNSS (sensors.gnss and gnss.csv): the "
                "keyframes are placed on the GNSS track");
  }
  OfflineCalibrationResult result;
  result.nominal = dataset.sensors.nominal_calibration;
  const bool use_wheel = problem.sensors.wheel && !dataset.wheel.empty();
  const sensors::EnuConverter enu = sensors::EnuConverter::AtFirstFix(dataset.gnss);
  for (const sensors::GnssFix& fix : dataset.gnss) {
    result.gnss_positions_W.push_back(enu.ToEnu(fix.lat_deg, fix.lon_deg, fix.alt_m));
  }

  // 1. Keyframes over the span the IMU and the fixes share.
  Report(options, "initializing", 0.0, 0.0, 0.0);
  const int64_t first_ns = std::max(dataset.imu.front().t_ns, dataset.gnss.front().t_ns);
  const int64_t last_ns = std::min(dataset.imu.back().t_ns, dataset.gnss.back().t_ns);
  const int64_t period_ns = SecondsToNs(options.inertial_keyframe_period_s);
  if (!(period_ns > 0)) throw Error("inertial_keyframe_period_s must be positive");
  std::vector<estimation::Keyframe> keyframes;
  for (int64_t t = first_ns; t <= last_ns; t += period_ns) {
    estimation::Keyframe kf;
    kf.t_ns = t;
    keyframes.push_back(kf);
  }
  if (keyframes.size() < 2) {
    throw Error("dataset " + dataset.directory +
                ": the IMU and the GNSS fixes overlap too briefly for two keyframes");
  }
  sensors::Calibration calibration = result.nominal;
  estimation::GnssInertialKeyframesOptions gnss_inertial;
  gnss_inertial.imu_noise = dataset.sensors.imu.noise;
  gnss_inertial.gravity_m_s2 = dataset.sensors.imu.gravity_m_s2;
  gnss_inertial.num_threads = problem.solver.num_threads;
  const estimation::GnssInertialKeyframes placed = estimation::KeyframesFromGnssAndImu(
      &keyframes, dataset.imu, use_wheel ? dataset.wheel : sensors::WheelSamples(), dataset.gnss,
      enu, calibration, gnss_inertial);
  result.seconds_initialization = SecondsSince(start);
  Report(options, "initializing", 1.0, 0.0, 0.0);

  // 2. The joint solve.
  const std::vector<CalibrationBlock> blocks_estimated =
      EstimatedBlocks(problem, dataset.sensors, options, use_wheel, true, &calibration);
  geometry::RightQuaternionManifold quaternion_manifold;
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem p(problem_options);
  for (estimation::Keyframe& kf : keyframes) {
    p.AddParameterBlock(kf.q_W_I.coeffs().data(), 4, &quaternion_manifold);
  }
  estimation::KeyframeImuOptions imu;
  imu.noise = dataset.sensors.imu.noise;
  imu.gravity_m_s2 = dataset.sensors.imu.gravity_m_s2;
  imu.num_threads = problem.solver.num_threads;
  estimation::AddImuFactors(&p, dataset.imu, &keyframes, imu);
  estimation::AddBiasPriors(&p, &keyframes.front(), gnss_inertial.gyro_bias_prior_sigma_rad_s,
                            gnss_inertial.accel_bias_prior_sigma_m_s2);
  SensorFactors sensor_factors{&dataset, &problem,   &result.nominal,    use_wheel, true,
                               &enu,     &blocks_estimated, &quaternion_manifold};
  sensor_factors.Add(&p, &keyframes, &calibration);
  for (auto& [sensor, rows] : WhitenedResidualsBySensor(&p)) {
    result.whitened_residuals[sensor].before = std::move(rows);
  }
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.max_num_iterations = problem.solver.max_iterations * problem.solver.outer_iterations;
  solver_options.num_threads = problem.solver.num_threads;
  Report(options, "solving", 0.0, 0.0, 0.0);
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &p, &summary);
  if (!summary.IsSolutionUsable()) {
    throw Error("dataset " + dataset.directory + ": the calibration solve failed: " +
                summary.message);
  }
  for (estimation::Keyframe& kf : keyframes) kf.q_W_I.normalize();
  for (auto& [sensor, rows] : WhitenedResidualsBySensor(&p)) {
    result.whitened_residuals[sensor].after = std::move(rows);
  }
  const BlockCovariance covariance = ComputeBlockCovariance(blocks_estimated, &p);
  result.batch.termination = summary.message;
  result.batch.final_cost = summary.final_cost;
  result.batch.calibration_per_iteration = {calibration};  // one solve
  io::CalibrationFile& file = result.calibration;
  file.solver["termination"] = summary.message;
  file.solver["iterations"] = std::to_string(summary.iterations.size());
  file.solver["final_cost"] = std::to_string(summary.final_cost);
  file.solver["gnss_factors"] = std::to_string(placed.gnss_factors);
  Conclude(dataset, problem, options, blocks_estimated, covariance, keyframes, &calibration, start,
           &result);
  return result;
}

}  // namespace pipeline
}  // namespace autocal
