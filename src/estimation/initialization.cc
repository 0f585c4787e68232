#include "autocal/estimation/initialization.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/geometry/quaternion_plus.h"
#include "autocal/geometry/so3.h"
#include "estimation/correlation_peak.h"
#include "estimation/gyro_unit.h"

namespace autocal {
namespace estimation {

namespace {

using geometry::Exp;
using geometry::Hat;

// Running per-axis mean and variance of a block of samples.
struct AxisStats {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d std = Eigen::Vector3d::Zero();
};

template <typename Get>
AxisStats Stats(const sensors::ImuSamples& imu, size_t begin, size_t end, Get get) {
  AxisStats s;
  const double n = static_cast<double>(end - begin);
  for (size_t i = begin; i < end; ++i) s.mean += get(imu[i]);
  s.mean /= n;
  Eigen::Vector3d var = Eigen::Vector3d::Zero();
  for (size_t i = begin; i < end; ++i) var += (get(imu[i]) - s.mean).cwiseAbs2();
  s.std = (var / std::max(1.0, n - 1.0)).cwiseSqrt();
  return s;
}

Eigen::Vector3d Gyro(const sensors::ImuSample& s) { return s.gyro_rad_s; }
Eigen::Vector3d Accel(const sensors::ImuSample& s) { return s.accel_m_s2; }

// Whether the gyro's scatter over [begin, end) changes from sample to sample as noise does:
// white noise differs between neighbours by about sqrt(2) times its standard deviation,
// while a turn on the spot about the gravity axis (the accelerometer steady, the rate
// changing smoothly) differs by a small fraction of it. Half the scatter leaves room for a
// sensor's own low-pass filter.
bool ScatterLooksLikeNoise(const sensors::ImuSamples& imu, size_t begin, size_t end,
                           const AxisStats& gyro) {
  int axis = 0;
  gyro.std.maxCoeff(&axis);
  double sum_sq = 0.0;
  for (size_t i = begin + 1; i < end; ++i) {
    const double d = imu[i].gyro_rad_s[axis] - imu[i - 1].gyro_rad_s[axis];
    sum_sq += d * d;
  }
  const double pairs = static_cast<double>(end - begin) - 1.0;
  if (pairs < 1.0) return false;
  return std::sqrt(sum_sq / pairs) > 0.5 * gyro.std[axis];
}

// The IMU step [t_i, t_i+1] holding t: i of the last sample at or before t (0 before the
// first).
size_t StepAt(const sensors::ImuSamples& imu, int64_t t_ns) {
  auto it = std::upper_bound(imu.begin(), imu.end(), t_ns,
                             [](int64_t t, const sensors::ImuSample& s) { return t < s.t_ns; });
  return static_cast<size_t>(std::max<std::ptrdiff_t>(0, (it - imu.begin()) - 1));
}

// The mean rate of step i (i + 1 < imu.size()), bias removed.
Eigen::Vector3d StepRate(const sensors::ImuSamples& imu, size_t i, const Eigen::Vector3d& bias) {
  return 0.5 * (imu[i].gyro_rad_s + imu[i + 1].gyro_rad_s) - bias;
}

// Orientation of the IMU at every sample time relative to the first sample, integrated with
// the mean rate of each step (bias removed), so that the rotation between any two instants
// is a lookup and one interpolation.
class GyroOrientationTable {
 public:
  GyroOrientationTable(const sensors::ImuSamples& imu, const Eigen::Vector3d& bias) : imu_(imu) {
    q_.reserve(imu.size());
    rate_.reserve(imu.size());
    q_.push_back(Eigen::Quaterniond::Identity());
    for (size_t i = 0; i + 1 < imu.size(); ++i) {
      const Eigen::Vector3d w = StepRate(imu, i, bias);
      rate_.push_back(w);
      const double dt = SecondsBetween(imu[i].t_ns, imu[i + 1].t_ns);
      q_.push_back(geometry::QuaternionPlus(q_.back(), Eigen::Vector3d(w * dt)));
    }
  }

  bool Covers(int64_t t_ns) const {
    return !imu_.empty() && t_ns >= imu_.front().t_ns && t_ns <= imu_.back().t_ns;
  }

  Eigen::Quaterniond At(int64_t t_ns) const {
    const size_t i = StepAt(imu_, t_ns);
    if (i + 1 >= imu_.size()) return q_.back();
    const double dt = SecondsBetween(imu_[i].t_ns, t_ns);
    return q_[i] * Exp(Eigen::Vector3d(rate_[i] * dt));
  }

 private:
  const sensors::ImuSamples& imu_;
  std::vector<Eigen::Quaterniond> q_;
  std::vector<Eigen::Vector3d> rate_;
};

// Left and right quaternion-product matrices in Eigen's [x, y, z, w] order:
// q (x) p = QuaternionLeft(q) p,  p (x) q = QuaternionRight(q) p.
Eigen::Matrix4d QuaternionLeft(const Eigen::Quaterniond& q) {
  Eigen::Matrix4d m;
  m.topLeftCorner<3, 3>() = q.w() * Eigen::Matrix3d::Identity() + Hat(q.vec());
  m.topRightCorner<3, 1>() = q.vec();
  m.bottomLeftCorner<1, 3>() = -q.vec().transpose();
  m(3, 3) = q.w();
  return m;
}

Eigen::Matrix4d QuaternionRight(const Eigen::Quaterniond& q) {
  Eigen::Matrix4d m;
  m.topLeftCorner<3, 3>() = q.w() * Eigen::Matrix3d::Identity() - Hat(q.vec());
  m.topRightCorner<3, 1>() = q.vec();
  m.bottomLeftCorner<1, 3>() = -q.vec().transpose();
  m(3, 3) = q.w();
  return m;
}

Eigen::Quaterniond PositiveW(const Eigen::Quaterniond& q) {
  return q.w() < 0.0 ? Eigen::Quaterniond(-q.coeffs()) : q;
}

// The rotation about the weakest axis (docs/estimation.md, "Hand-eye rotation"). In the
// tangent of the solution x, the stacked system's squared singular values are the information
// of the pairs' angular residuals per unit noise, sum_i w_i^2 4 sin^2(a_i / 2) (1 - (b_i . e)^2)
// for pair rotations a_i about axes b_i and a direction e. The noise adds a floor, which the
// smallest squared singular value s3^2 (the residual at x) measures; the residuals' per-axis
// standard deviation is sigma = sqrt(4 s3^2 / (3 sum w_i^2 - 3)). A pair that turned by less
// than a few sigma carries no axis, only noise, and its floor is not isotropic: thousands of
// them fake motion about any axis. So the motion about the weakest axis, m = sqrt(s2^2 - s3^2),
// is taken from the system of the pairs whose IMU rotation exceeds min_sigmas * sigma, and the
// rotation about that axis has standard deviation sigma / m.
void WeakestAxis(const std::vector<Eigen::Matrix4d>& blocks, const std::vector<double>& weights,
                 const std::vector<Eigen::Quaterniond>& imu_rotations,
                 const Eigen::Vector4d& singular_values, double min_sigmas, HandEyeRotation* out) {
  double weight_sq_sum = 0.0;
  for (double w : weights) weight_sq_sum += w * w;
  const double s3_sq = singular_values(3) * singular_values(3);
  const double sigma_rad = std::sqrt(4.0 * s3_sq / std::max(1.0, 3.0 * weight_sq_sum - 3.0));
  std::vector<size_t> turning;
  for (size_t i = 0; i < blocks.size(); ++i) {
    if (geometry::AngleOf(imu_rotations[i]) > min_sigmas * sigma_rad) turning.push_back(i);
  }
  out->turning_pairs = static_cast<int>(turning.size());
  double motion_sq = 0.0;
  if (turning.size() >= 2) {
    Eigen::MatrixXd A(4 * turning.size(), 4);
    for (size_t k = 0; k < turning.size(); ++k) {
      A.middleRows<4>(4 * k) = weights[turning[k]] * blocks[turning[k]];
    }
    const Eigen::Vector4d s = Eigen::JacobiSVD<Eigen::MatrixXd>(A).singularValues();
    motion_sq = s(2) * s(2) - s(3) * s(3);
  }
  out->weakest_axis_rotation_rad = std::sqrt(std::max(0.0, motion_sq));
  out->weakest_axis_std_rad =
      motion_sq > 0.0 ? sigma_rad / std::sqrt(motion_sq) : std::numeric_limits<double>::infinity();
}

}  // namespace

namespace {

StillStart DetectStillStartAsLogged(const sensors::ImuSamples& imu,
                                    const StillStartOptions& options) {
  StillStart out;
  if (imu.size() < 2) {
    out.reason = "too few IMU samples";
    return out;
  }
  // Blocks of a quarter of the minimum duration are classified still or moving; the first
  // run of still blocks long enough is the still start.
  const int64_t block_ns = SecondsToNs(0.25 * options.min_duration_s);
  const int64_t search_end_ns = imu.front().t_ns + SecondsToNs(options.max_search_s);
  std::vector<std::pair<size_t, size_t>> blocks;
  size_t begin = 0;
  while (begin < imu.size() && imu[begin].t_ns < search_end_ns) {
    size_t end = begin;
    while (end < imu.size() && imu[end].t_ns < imu[begin].t_ns + block_ns) ++end;
    if (end - begin < 3) break;
    blocks.emplace_back(begin, end);
    begin = end;
  }
  // The first run of at least min_duration_s wins (else the longest, to report it): a later
  // steady stretch, e.g. cruising straight, also passes the thresholds but is not at rest.
  const size_t min_blocks = 4;
  size_t run_begin = 0;
  size_t best_begin = 0, best_end = 0;
  for (size_t b = 0; b <= blocks.size(); ++b) {
    bool still = false;
    if (b < blocks.size()) {
      const AxisStats g = Stats(imu, blocks[b].first, blocks[b].second, Gyro);
      const AxisStats a = Stats(imu, blocks[b].first, blocks[b].second, Accel);
      still = g.std.maxCoeff() <= options.max_gyro_std_rad_s &&
              a.std.maxCoeff() <= options.max_accel_std_m_s2 &&
              g.mean.norm() <= options.max_gyro_mean_rad_s;
    }
    if (!still) {
      if (b > run_begin && b - run_begin > best_end - best_begin) {
        best_begin = run_begin;
        best_end = b;
      }
      if (best_end - best_begin >= min_blocks) break;
      run_begin = b + 1;
    }
  }
  if (best_end == best_begin) {
    out.reason = "no still period in the first " + std::to_string(options.max_search_s) + " s";
    return out;
  }
  const size_t first = blocks[best_begin].first;
  const size_t last = blocks[best_end - 1].second;
  out.t_begin_ns = imu[first].t_ns;
  out.t_end_ns = imu[last - 1].t_ns;
  if (SecondsBetween(out.t_begin_ns, out.t_end_ns) < 0.75 * options.min_duration_s) {
    out.reason =
        "the longest still period is shorter than " + std::to_string(options.min_duration_s) + " s";
    return out;
  }
  const AxisStats g = Stats(imu, first, last, Gyro);
  const AxisStats a = Stats(imu, first, last, Accel);
  out.gyro_bias_rad_s = g.mean;
  out.gravity_m_s2 = a.mean.norm();
  // At rest the specific force is R_W_I^T (0, 0, g): f = g (-sin p, sin r cos p, cos r cos p)
  // for R_W_I = Rz(0) Ry(p) Rx(r).
  const Eigen::Vector3d& f = a.mean;
  const double roll = std::atan2(f.y(), f.z());
  const double pitch = std::atan2(-f.x(), std::hypot(f.y(), f.z()));
  out.q_W_I = Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
              Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX());
  out.found = true;
  return out;
}

}  // namespace

namespace internal {

std::optional<GyroInDegreesAtRest> FindGyroInDegreesAtRest(const sensors::ImuSamples& imu,
                                                           const StillStartOptions& options) {
  if (imu.size() < 2 || DetectStillStartAsLogged(imu, options).found) return std::nullopt;
  // The search covers the first max_search_s seconds (and the block that crosses it).
  const int64_t end_ns =
      imu.front().t_ns + SecondsToNs(options.max_search_s + options.min_duration_s);
  sensors::ImuSamples scaled;
  for (const sensors::ImuSample& sample : imu) {
    if (sample.t_ns > end_ns) break;
    scaled.push_back(sample);
    scaled.back().gyro_rad_s *= kDegToRad;
  }
  const StillStart in_degrees = DetectStillStartAsLogged(scaled, options);
  if (!in_degrees.found) return std::nullopt;
  const auto in_range = [](int64_t t) {
    return [t](const sensors::ImuSample& s) { return s.t_ns >= t; };
  };
  const size_t first = static_cast<size_t>(
      std::find_if(imu.begin(), imu.end(), in_range(in_degrees.t_begin_ns)) - imu.begin());
  const size_t last = static_cast<size_t>(
      std::find_if(imu.begin(), imu.end(), in_range(in_degrees.t_end_ns + 1)) - imu.begin());
  const AxisStats g = Stats(imu, first, last, Gyro);
  if (!(g.std.maxCoeff() > options.max_gyro_std_rad_s)) return std::nullopt;
  if (!ScatterLooksLikeNoise(imu, first, last, g)) return std::nullopt;
  GyroInDegreesAtRest out;
  out.first_sample = first;
  out.duration_s = SecondsBetween(in_degrees.t_begin_ns, in_degrees.t_end_ns);
  out.gyro_std_as_read = g.std.maxCoeff();
  out.gyro_mean_as_read = g.mean.norm();
  return out;
}

}  // namespace internal

StillStart DetectStillStart(const sensors::ImuSamples& imu, const StillStartOptions& options) {
  StillStart out = DetectStillStartAsLogged(imu, options);
  if (out.found) return out;
  if (const auto degrees = internal::FindGyroInDegreesAtRest(imu, options)) {
    // A hint, not a verdict: a very noisy gyro in rad/s scatters like this too (the dataset
    // reader, which knows the stated noise density, decides).
    out.reason += "; yet the accelerometer is steady for " + FormatFixed(degrees->duration_s, 1) +
                  " s from sample " + std::to_string(degrees->first_sample) +
                  ", where the gyro scatters by " + FormatFixed(degrees->gyro_std_as_read, 4) +
                  " (per-axis std), a still gyro's noise if it is read as deg/s: is the gyro "
                  "logged in deg/s? autocal expects rad/s";
  }
  return out;
}

Eigen::Quaterniond IntegrateGyro(const sensors::ImuSamples& imu, const Eigen::Vector3d& gyro_bias,
                                 int64_t t0_ns, int64_t t1_ns) {
  if (imu.empty() || t0_ns < imu.front().t_ns || t1_ns > imu.back().t_ns || t1_ns < t0_ns) {
    throw Error("IntegrateGyro: the IMU samples do not cover the requested interval");
  }
  // Only the steps inside [t0, t1], each at its mean rate (as GyroOrientationTable): a
  // hand-eye pair costs its own samples, not the log's.
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  int64_t t_ns = t0_ns;
  for (size_t i = StepAt(imu, t0_ns); t_ns < t1_ns && i + 1 < imu.size(); ++i) {
    const int64_t next_ns = std::min(imu[i + 1].t_ns, t1_ns);
    const Eigen::Vector3d w = StepRate(imu, i, gyro_bias);
    q = geometry::QuaternionPlus(q, Eigen::Vector3d(w * SecondsBetween(t_ns, next_ns)));
    t_ns = next_ns;
  }
  return q;
}

namespace {

// Throws autocal::Error unless the search range lies in (0, kMaxTimeOffsetSearchRangeS] and
// the step in (0, range].
void CheckTimeOffsetOptions(const TimeOffsetOptions& options) {
  const double range_s = options.search_range_s;
  if (!(range_s > 0.0 && range_s <= kMaxTimeOffsetSearchRangeS)) {
    throw Error("EstimateTimeOffset: search_range_s must lie in (0, " +
                FormatShort(kMaxTimeOffsetSearchRangeS) + "] s, got " + FormatShort(range_s));
  }
  if (!(options.step_s > 0.0 && options.step_s <= range_s)) {
    throw Error("EstimateTimeOffset: step_s must lie in (0, search_range_s = " +
                FormatShort(range_s) + "] s, got " + FormatShort(options.step_s));
  }
}

}  // namespace

TimeOffsetEstimate EstimateTimeOffset(const std::vector<RelativeRotation>& lidar_rotations,
                                      const sensors::ImuSamples& imu,
                                      const Eigen::Vector3d& gyro_bias_rad_s,
                                      const TimeOffsetOptions& options) {
  CheckTimeOffsetOptions(options);
  TimeOffsetEstimate out;
  const GyroOrientationTable table(imu, gyro_bias_rad_s);
  const int64_t range_ns = SecondsToNs(options.search_range_s);
  // Intervals usable for every candidate offset.
  std::vector<const RelativeRotation*> usable;
  std::vector<double> lidar_rate;
  for (const RelativeRotation& r : lidar_rotations) {
    if (r.t1_ns <= r.t0_ns) continue;
    if (!table.Covers(r.t0_ns - range_ns) || !table.Covers(r.t1_ns + range_ns)) continue;
    usable.push_back(&r);
    lidar_rate.push_back(geometry::AngleOf(r.q_0_1) / SecondsBetween(r.t0_ns, r.t1_ns));
  }
  if (usable.size() < 10) {
    out.reason = "fewer than 10 LiDAR relative rotations inside the IMU's time span";
    return out;
  }
  std::vector<double> imu_rate(usable.size());
  const internal::CorrelationScan scan =
      internal::ScanCorrelation(0.0, options.search_range_s, options.step_s, [&](double offset_s) {
        const int64_t offset_ns = SecondsToNs(offset_s);
        for (size_t i = 0; i < usable.size(); ++i) {
          const Eigen::Quaterniond q = table.At(usable[i]->t0_ns + offset_ns).conjugate() *
                                       table.At(usable[i]->t1_ns + offset_ns);
          imu_rate[i] = geometry::AngleOf(q) / SecondsBetween(usable[i]->t0_ns, usable[i]->t1_ns);
        }
        return internal::Pearson(lidar_rate, imu_rate);
      });
  out.candidate_offsets_s = scan.offsets_s;
  out.correlation = scan.correlation;
  out.peak_correlation = scan.correlation[scan.peak];
  out.offset_s = scan.refined_offset_s;
  if (scan.peak_at_edge) {
    out.reason = "the correlation peaks at the edge of the search range";
    return out;
  }
  if (out.peak_correlation < options.min_peak_correlation) {
    out.reason = "angular-rate correlation " + std::to_string(out.peak_correlation) +
                 " is too weak: the drive needs more varied turning";
    return out;
  }
  out.reliable = true;
  return out;
}

HandEyeRotation SolveHandEyeRotation(const std::vector<Eigen::Quaterniond>& imu_rotations,
                                     const std::vector<Eigen::Quaterniond>& lidar_rotations,
                                     const HandEyeOptions& options) {
  if (imu_rotations.size() != lidar_rotations.size()) {
    throw Error("SolveHandEyeRotation: IMU and LiDAR rotation lists differ in length");
  }
  HandEyeRotation out;
  const size_t n = imu_rotations.size();
  if (n < 3) {
    out.reason = "fewer than 3 rotation pairs";
    return out;
  }
  std::vector<Eigen::Matrix4d> blocks(n);
  for (size_t i = 0; i < n; ++i) {
    blocks[i] = QuaternionLeft(PositiveW(imu_rotations[i])) -
                QuaternionRight(PositiveW(lidar_rotations[i]));
  }
  std::vector<double> weights(n, 1.0), solved_weights;
  Eigen::Quaterniond x = Eigen::Quaterniond::Identity();
  Eigen::Vector4d singular_values = Eigen::Vector4d::Zero();
  for (int iteration = 0; iteration < std::max(1, options.robust_iterations); ++iteration) {
    Eigen::MatrixXd A(4 * n, 4);
    for (size_t i = 0; i < n; ++i) A.middleRows<4>(4 * i) = weights[i] * blocks[i];
    solved_weights = weights;
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeThinV);
    x.coeffs() = svd.matrixV().col(3);
    x.normalize();
    singular_values = svd.singularValues();
    double sum_sq = 0.0;
    for (size_t i = 0; i < n; ++i) {
      const double r = geometry::AngularDistance(Eigen::Quaterniond(imu_rotations[i] * x),
                                                 Eigen::Quaterniond(x * lidar_rotations[i]));
      sum_sq += r * r;
      weights[i] =
          r <= options.huber_threshold_rad ? 1.0 : std::sqrt(options.huber_threshold_rad / r);
    }
    out.rms_residual_rad = std::sqrt(sum_sq / static_cast<double>(n));
  }
  out.q_I_L = PositiveW(x);
  out.singular_value_ratio = singular_values(2) / std::max(singular_values(0), 1e-300);
  WeakestAxis(blocks, solved_weights, imu_rotations, singular_values,
              options.min_turning_pair_sigmas, &out);
  if (out.singular_value_ratio < options.min_singular_value_ratio) {
    out.reason = "the rotations do not excite two independent axes (planar motion?)";
    return out;
  }
  if (out.weakest_axis_rotation_rad < options.min_weakest_axis_rotation_rad) {
    out.reason = "the rotations turn about their weakest axis by " +
                 FormatShort(out.weakest_axis_rotation_rad) + " rad (root-sum-square over the " +
                 std::to_string(out.turning_pairs) + " of " + std::to_string(n) +
                 " pairs that turned beyond the noise), need " +
                 FormatShort(options.min_weakest_axis_rotation_rad) +
                 ": the motion about two axes does not rise above the noise";
    return out;
  }
  if (out.weakest_axis_std_rad > options.max_weakest_axis_std_rad) {
    out.reason = "the rotation about the weakest axis is uncertain by " +
                 FormatShort(out.weakest_axis_std_rad * kRadToDeg) + " deg (limit " +
                 FormatShort(options.max_weakest_axis_std_rad * kRadToDeg) +
                 " deg): the rotations are too noisy for their size";
    return out;
  }
  out.observable = true;
  return out;
}

HandEyeTranslation SolveHandEyeTranslation(const std::vector<Eigen::Quaterniond>& imu_rotations,
                                           const std::vector<Eigen::Vector3d>& imu_translations,
                                           const std::vector<Eigen::Vector3d>& lidar_translations,
                                           const Eigen::Quaterniond& q_I_L,
                                           const Eigen::Vector3d& p_I_L_prior,
                                           double min_singular_value) {
  const size_t n = imu_rotations.size();
  if (imu_translations.size() != n || lidar_translations.size() != n) {
    throw Error("SolveHandEyeTranslation: input lists differ in length");
  }
  HandEyeTranslation out;
  out.p_I_L = p_I_L_prior;
  if (n == 0) return out;
  Eigen::MatrixXd A(3 * n, 3);
  Eigen::VectorXd b(3 * n);
  for (size_t i = 0; i < n; ++i) {
    A.middleRows<3>(3 * i) = imu_rotations[i].toRotationMatrix() - Eigen::Matrix3d::Identity();
    b.segment<3>(3 * i) = q_I_L * lidar_translations[i] - imu_translations[i];
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeThinU | Eigen::ComputeThinV);
  out.singular_values = svd.singularValues();
  // Correct the prior only along excited directions.
  const Eigen::VectorXd residual = b - A * p_I_L_prior;
  Eigen::Vector3d correction = Eigen::Vector3d::Zero();
  Eigen::Matrix3d projector = Eigen::Matrix3d::Zero();
  for (int k = 0; k < 3; ++k) {
    if (out.singular_values(k) < min_singular_value) continue;
    const Eigen::Vector3d v = svd.matrixV().col(k);
    correction += v * (svd.matrixU().col(k).dot(residual) / out.singular_values(k));
    projector += v * v.transpose();
  }
  out.p_I_L = p_I_L_prior + correction;
  for (int axis = 0; axis < 3; ++axis) out.observable(axis) = projector(axis, axis) > 0.9;
  return out;
}

}  // namespace estimation
}  // namespace autocal
