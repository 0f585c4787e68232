#include "autocal/estimation/keyframe_sensor_factors.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>

#include <Eigen/Geometry>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/geometry/manifolds.h"

namespace autocal {
namespace estimation {
namespace {

// The samples bracketing an instant and the weight of the later one (Eq. K1):
// x(t) = (1 - s) x[first] + s x[second].
struct Bracket {
  size_t first = 0;
  size_t second = 0;
  double s = 0.0;
};

template <typename Sample>
void CheckIncreasing(const std::vector<Sample>& samples, const std::string& what) {
  for (size_t i = 1; i < samples.size(); ++i) {
    if (samples[i].t_ns <= samples[i - 1].t_ns) {
      throw Error(what + " stamps must increase: sample " + std::to_string(i) + " at " +
                  std::to_string(samples[i].t_ns) + " ns follows " +
                  std::to_string(samples[i - 1].t_ns) + " ns");
    }
  }
}

// A sample exactly at t_ns is used alone; otherwise the two around it, unless they are more
// than max_gap_ns apart or t_ns lies outside the samples.
template <typename Sample>
std::optional<Bracket> FindBracket(const std::vector<Sample>& samples, int64_t t_ns,
                                   int64_t max_gap_ns) {
  const auto it = std::lower_bound(samples.begin(), samples.end(), t_ns,
                                   [](const Sample& a, int64_t t) { return a.t_ns < t; });
  if (it == samples.end()) return std::nullopt;
  const size_t second = static_cast<size_t>(it - samples.begin());
  if (it->t_ns == t_ns) return Bracket{second, second, 0.0};
  if (second == 0) return std::nullopt;
  const size_t first = second - 1;
  const int64_t gap_ns = samples[second].t_ns - samples[first].t_ns;
  if (gap_ns > max_gap_ns) return std::nullopt;
  return Bracket{first, second,
                 static_cast<double>(t_ns - samples[first].t_ns) / static_cast<double>(gap_ns)};
}

int64_t GapNs(double gap_s, const std::string& name) {
  if (!std::isfinite(gap_s) || !(gap_s > 0.0)) {
    throw Error(name + " must be a positive number of seconds, got " + std::to_string(gap_s));
  }
  return SecondsToNs(gap_s);
}

// InterpolateGnss on fixes known to be in time order.
bool InterpolateSortedGnss(const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
                           int64_t t_ns, int64_t max_gap_ns,
                           factors::GnssMeasurement* measurement) {
  const std::optional<Bracket> b = FindBracket(fixes, t_ns, max_gap_ns);
  if (!b) return false;
  const sensors::GnssFix& f0 = fixes[b->first];
  const sensors::GnssFix& f1 = fixes[b->second];
  measurement->p_W_A = (1.0 - b->s) * converter.ToEnu(f0) + b->s * converter.ToEnu(f1);
  // Eq. K2: the interpolated sigma bounds the true one, sqrt((1-s)^2 s0^2 + s^2 s1^2), from
  // above, and stays right when the errors of neighbouring fixes are correlated.
  measurement->sigma_enu_m = (1.0 - b->s) * f0.std_enu_m + b->s * f1.std_enu_m;
  return true;
}

// Ceres would treat a quaternion added implicitly by AddResidualBlock as a Euclidean 4-vector.
void RequireQuaternionBlock(const ceres::Problem& problem, const Eigen::Quaterniond& q,
                            const std::string& name) {
  const double* block = q.coeffs().data();
  if (!problem.HasParameterBlock(block) || dynamic_cast<const geometry::RightQuaternionManifold*>(
                                               problem.GetManifold(block)) == nullptr) {
    throw Error(name +
                " must be added to the problem with geometry::RightQuaternionManifold before its "
                "wheel or GNSS factors");
  }
}

void SetConstantUnless(bool estimate, double* block, ceres::Problem* problem) {
  if (!estimate) problem->SetParameterBlockConstant(block);
}

// Least-squares yaw and translation (Eqs. K3, K4) that map the points a onto g, over the
// pairs flagged in `use`.
void FitYawAndTranslation(const std::vector<Eigen::Vector3d>& a,
                          const std::vector<Eigen::Vector3d>& g, const std::vector<bool>& use,
                          double min_horizontal_extent_m, GnssAlignment* fit) {
  Eigen::Vector3d a_mean = Eigen::Vector3d::Zero(), g_mean = Eigen::Vector3d::Zero();
  int n = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    if (!use[k]) continue;
    a_mean += a[k];
    g_mean += g[k];
    ++n;
  }
  if (n < 2) throw Error("AlignKeyframesToGnss: fewer than two keyframes with a usable GNSS fix");
  a_mean /= n;
  g_mean /= n;
  double s_cos = 0.0, s_sin = 0.0, spread_m2 = 0.0;
  for (size_t k = 0; k < a.size(); ++k) {
    if (!use[k]) continue;
    const Eigen::Vector2d da = (a[k] - a_mean).head<2>();
    const Eigen::Vector2d dg = (g[k] - g_mean).head<2>();
    s_cos += da.dot(dg);
    s_sin += da.x() * dg.y() - da.y() * dg.x();
    spread_m2 += da.squaredNorm();
  }
  if (std::sqrt(spread_m2 / n) < min_horizontal_extent_m) {
    throw Error("AlignKeyframesToGnss: the keyframes span " +
                std::to_string(std::sqrt(spread_m2 / n)) + " m (RMS) horizontally, less than " +
                std::to_string(min_horizontal_extent_m) + " m: the yaw is unobservable");
  }
  fit->yaw_rad = std::atan2(s_sin, s_cos);
  fit->translation_m = g_mean - Eigen::AngleAxisd(fit->yaw_rad, Eigen::Vector3d::UnitZ()) * a_mean;
  fit->num_inliers = n;
}

}  // namespace

int AddWheelFactors(ceres::Problem* problem, const sensors::ImuSamples& imu,
                    const sensors::WheelSamples& wheel, std::vector<Keyframe>* keyframes,
                    sensors::Calibration* calibration, const KeyframeWheelOptions& options) {
  const int64_t max_wheel_gap_ns = GapNs(options.max_wheel_gap_s, "max_wheel_gap_s");
  const int64_t max_imu_gap_ns = GapNs(options.max_imu_gap_s, "max_imu_gap_s");
  CheckIncreasing(wheel, "AddWheelFactors: wheel");
  CheckIncreasing(imu, "AddWheelFactors: IMU");
  RequireQuaternionBlock(*problem, calibration->q_I_V, "q_I_V");
  for (const Keyframe& kf : *keyframes) {
    RequireQuaternionBlock(*problem, kf.q_W_I, "keyframe q_W_I");
  }

  sensors::Calibration& c = *calibration;
  // One loss for all the factors (the problem deletes a shared loss once); it is ours to
  // delete until a residual block uses it.
  std::unique_ptr<ceres::LossFunction> unused_loss(factors::MakeLossFunction(options.loss));
  ceres::LossFunction* loss = unused_loss.get();
  int added = 0;
  for (Keyframe& kf : *keyframes) {
    const std::optional<Bracket> w = FindBracket(wheel, kf.t_ns, max_wheel_gap_ns);
    const std::optional<Bracket> g = FindBracket(imu, kf.t_ns, max_imu_gap_ns);
    if (!w || !g) continue;
    const sensors::WheelSample& w0 = wheel[w->first];
    const sensors::WheelSample& w1 = wheel[w->second];
    factors::WheelMeasurement m;
    m.left_rad_s = (1.0 - w->s) * w0.left_rad_s + w->s * w1.left_rad_s;
    m.right_rad_s = (1.0 - w->s) * w0.right_rad_s + w->s * w1.right_rad_s;
    m.gyro_rad_s = (1.0 - g->s) * imu[g->first].gyro_rad_s + g->s * imu[g->second].gyro_rad_s;

    std::vector<double*> blocks = {
        kf.q_W_I.coeffs().data(), kf.v_W_I.data(), kf.b_g.data(),
        c.q_I_V.coeffs().data(),  c.p_I_V.data(),  &c.wheel_radius_left_m};
    if (!options.factor.shared_radius) blocks.push_back(&c.wheel_radius_right_m);
    blocks.push_back(&c.track_width_m);
    problem->AddResidualBlock(factors::WheelFactor::Create(m, options.factor), loss, blocks);
    unused_loss.release();
    ++added;
  }
  if (added == 0) return 0;
  SetConstantUnless(options.estimate_vehicle_rotation, c.q_I_V.coeffs().data(), problem);
  SetConstantUnless(options.estimate_vehicle_translation, c.p_I_V.data(), problem);
  SetConstantUnless(options.estimate_radii, &c.wheel_radius_left_m, problem);
  if (!options.factor.shared_radius) {
    SetConstantUnless(options.estimate_radii, &c.wheel_radius_right_m, problem);
  }
  SetConstantUnless(options.estimate_track_width, &c.track_width_m, problem);
  return added;
}

bool InterpolateGnss(const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
                     int64_t t_ns, double max_fix_gap_s, factors::GnssMeasurement* measurement) {
  CheckIncreasing(fixes, "GNSS fix");
  return InterpolateSortedGnss(fixes, converter, t_ns, GapNs(max_fix_gap_s, "max_fix_gap_s"),
                               measurement);
}

int AddGnssFactors(ceres::Problem* problem, const sensors::GnssFixes& fixes,
                   const sensors::EnuConverter& converter, std::vector<Keyframe>* keyframes,
                   sensors::Calibration* calibration, const KeyframeGnssOptions& options) {
  const int64_t max_gap_ns = GapNs(options.max_fix_gap_s, "max_fix_gap_s");
  CheckIncreasing(fixes, "AddGnssFactors: GNSS fix");
  for (const Keyframe& kf : *keyframes) {
    RequireQuaternionBlock(*problem, kf.q_W_I, "keyframe q_W_I");
  }

  // One loss for all the factors (the problem deletes a shared loss once); it is ours to
  // delete until a residual block uses it.
  std::unique_ptr<ceres::LossFunction> unused_loss(factors::MakeLossFunction(options.loss));
  ceres::LossFunction* loss = unused_loss.get();
  int added = 0;
  for (Keyframe& kf : *keyframes) {
    factors::GnssMeasurement m;
    if (!InterpolateSortedGnss(fixes, converter, kf.t_ns, max_gap_ns, &m)) continue;
    problem->AddResidualBlock(factors::GnssFactor::Create(m), loss, kf.q_W_I.coeffs().data(),
                              kf.p_W_I.data(), calibration->p_I_A.data());
    unused_loss.release();
    ++added;
  }
  if (added > 0) SetConstantUnless(options.estimate_lever_arm, calibration->p_I_A.data(), problem);
  return added;
}

GnssAlignment AlignKeyframesToGnss(std::vector<Keyframe>* keyframes,
                                   const sensors::GnssFixes& fixes,
                                   const sensors::EnuConverter& converter,
                                   const Eigen::Vector3d& p_I_A,
                                   const GnssAlignmentOptions& options) {
  // Pairs: the antenna in the keyframes' frame (a) and its interpolated fix in ENU (g).
  const int64_t max_gap_ns = GapNs(options.max_fix_gap_s, "max_fix_gap_s");
  CheckIncreasing(fixes, "AlignKeyframesToGnss: GNSS fix");
  std::vector<Eigen::Vector3d> a, g;
  for (const Keyframe& kf : *keyframes) {
    factors::GnssMeasurement m;
    if (!InterpolateSortedGnss(fixes, converter, kf.t_ns, max_gap_ns, &m)) continue;
    a.push_back(kf.p_W_I + kf.q_W_I * p_I_A);
    g.push_back(m.p_W_A);
  }
  GnssAlignment fit;
  fit.num_pairs = static_cast<int>(a.size());
  std::vector<bool> inlier(a.size(), true);
  std::vector<double> distance_m(a.size());
  auto distances = [&]() {
    const Eigen::AngleAxisd R_z(fit.yaw_rad, Eigen::Vector3d::UnitZ());
    for (size_t k = 0; k < a.size(); ++k) {
      distance_m[k] = (R_z * a[k] + fit.translation_m - g[k]).norm();
    }
  };
  FitYawAndTranslation(a, g, inlier, options.min_horizontal_extent_m, &fit);
  for (int refit = 0; refit < options.max_refits; ++refit) {
    distances();
    std::vector<double> sorted = distance_m;
    const auto middle = sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2);
    std::nth_element(sorted.begin(), middle, sorted.end());
    const double median_m = *middle;
    const double gate_m =
        std::max(options.min_outlier_distance_m, options.outlier_mad_factor * 1.4826 * median_m);
    std::vector<bool> next(a.size());
    for (size_t k = 0; k < a.size(); ++k) next[k] = distance_m[k] <= gate_m;
    if (next == inlier) break;
    inlier = next;
    FitYawAndTranslation(a, g, inlier, options.min_horizontal_extent_m, &fit);
  }
  distances();
  double sum_m2 = 0.0;
  for (size_t k = 0; k < a.size(); ++k) {
    if (inlier[k]) sum_m2 += distance_m[k] * distance_m[k];
  }
  fit.rms_m = std::sqrt(sum_m2 / fit.num_inliers);

  // Eq. K5 on every state.
  const Eigen::Quaterniond q_z(Eigen::AngleAxisd(fit.yaw_rad, Eigen::Vector3d::UnitZ()));
  for (Keyframe& kf : *keyframes) {
    kf.q_W_I = (q_z * kf.q_W_I).normalized();
    kf.p_W_I = q_z * kf.p_W_I + fit.translation_m;
    kf.v_W_I = q_z * kf.v_W_I;
  }
  return fit;
}

}  // namespace estimation
}  // namespace autocal
