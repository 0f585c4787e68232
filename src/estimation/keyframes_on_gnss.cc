// Keyframes moved onto GNSS (docs/keyframe_factors.md, "Keyframes from GNSS"): a rigid yaw and
// translation of a whole trajectory onto the fixes (Eqs. K3-K5), and each keyframe placed on a
// local quadratic fit of the antenna track (Eq. K7).
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/time.h"
#include "autocal/estimation/clock_offsets.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "common/order_statistics.h"
#include "estimation/keyframe_interpolation.h"

namespace autocal {
namespace estimation {
namespace {

using autocal::internal::Median;
using internal::CheckIncreasing;
using internal::ForwardHeading;
using internal::GapNsOrFromStamps;
using internal::InterpolateSortedGnss;
using internal::NearestFlagged;
using internal::WrapAngle;

// Distances to a fit beyond this are outliers: a multiple of the median distance's robust
// sigma (1.4826 * median for a Gaussian), never below a floor.
double OutlierGate(double median_m, double min_distance_m, double mad_factor) {
  return std::max(min_distance_m, mad_factor * 1.4826 * median_m);
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

sensors::GnssFixes FixesOnImuClock(sensors::GnssFixes fixes, double time_offset_gnss_imu_s) {
  if (!std::isfinite(time_offset_gnss_imu_s)) {
    throw Error("FixesOnImuClock: the GNSS time offset must be finite");
  }
  return Shifted(std::move(fixes), time_offset_gnss_imu_s);
}

GnssAlignment AlignKeyframesToGnss(std::vector<Keyframe>* keyframes,
                                   const sensors::GnssFixes& fixes,
                                   const sensors::EnuConverter& converter,
                                   const Eigen::Vector3d& p_I_A,
                                   const GnssAlignmentOptions& options) {
  // Pairs: the antenna in the keyframes' frame (a) and its interpolated fix in ENU (g).
  CheckIncreasing(fixes, "AlignKeyframesToGnss: GNSS fix");
  const int64_t max_gap_ns = GapNsOrFromStamps(options.max_fix_gap_s, fixes, "max_fix_gap_s");
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
    const double gate_m =
        OutlierGate(Median(distance_m), options.min_outlier_distance_m, options.outlier_mad_factor);
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

namespace {

// The value at at_ns of a line fitted to the differences d over [begin, end) against their
// times (a drift's local rate keeps an outage on one side of a window from biasing it). It
// starts from the per-axis median and a zero rate; each of two least-squares fits takes the
// pairs within the outlier gate of the line before.
Eigen::Vector3d LocalLineAt(const std::vector<int64_t>& t_ns, const std::vector<Eigen::Vector3d>& d,
                            size_t begin, size_t end, int64_t at_ns,
                            const OdometryDriftOptions& options) {
  Eigen::Matrix<double, 2, 3> line = Eigen::Matrix<double, 2, 3>::Zero();
  std::vector<double> axis(end - begin);
  for (int a = 0; a < 3; ++a) {
    for (size_t i = begin; i < end; ++i) axis[i - begin] = d[i](a);
    line(0, a) = Median(axis);
  }
  std::vector<Eigen::Vector2d> x(end - begin);  // (1, time from at_ns)
  for (size_t i = begin; i < end; ++i) x[i - begin] = {1.0, NsToSeconds(t_ns[i] - at_ns)};
  std::vector<double> distance_m(end - begin);
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t i = begin; i < end; ++i) {
      distance_m[i - begin] = (d[i] - line.transpose() * x[i - begin]).norm();
    }
    const double gate_m =
        OutlierGate(Median(distance_m), options.min_outlier_distance_m, options.outlier_mad_factor);
    Eigen::Matrix2d normal = Eigen::Matrix2d::Zero();
    Eigen::Matrix<double, 2, 3> rhs = Eigen::Matrix<double, 2, 3>::Zero();
    int used = 0;
    for (size_t i = begin; i < end; ++i) {
      if (distance_m[i - begin] > gate_m) continue;
      normal += x[i - begin] * x[i - begin].transpose();
      rhs += x[i - begin] * d[i].transpose();
      ++used;
    }
    // Too few pairs, or all at one instant: the line before stands.
    if (used < std::max(options.min_pairs, 2) || !(normal.determinant() > 1e-9)) break;
    line = normal.ldlt().solve(rhs);
  }
  return line.row(0).transpose();
}

// Each empty entry takes the value of the nearest one (before or after) that has one. False when
// none has.
bool FillFromNearest(std::vector<std::optional<Eigen::Vector3d>>* values) {
  std::vector<std::optional<Eigen::Vector3d>>& v = *values;
  std::vector<std::optional<size_t>> before(v.size()), after(v.size());
  std::optional<size_t> last;
  for (size_t k = 0; k < v.size(); ++k) {
    if (v[k]) last = k;
    before[k] = last;
  }
  last.reset();
  for (size_t k = v.size(); k-- > 0;) {
    if (v[k]) last = k;
    after[k] = last;
  }
  if (!last) return false;
  for (size_t k = 0; k < v.size(); ++k) {
    if (v[k]) continue;
    const std::optional<size_t>& b = before[k];
    const std::optional<size_t>& a = after[k];
    v[k] = v[!b ? *a : !a ? *b : (k - *b <= *a - k ? *b : *a)];
  }
  return true;
}

double MedianDistance(const std::vector<Eigen::Vector3d>& d) {
  std::vector<double> distance_m;
  for (const Eigen::Vector3d& v : d) distance_m.push_back(v.norm());
  return distance_m.empty() ? 0.0 : Median(distance_m);
}

}  // namespace

OdometryDrift RemoveOdometryDrift(std::vector<Keyframe>* keyframes, const sensors::GnssFixes& fixes,
                                  const sensors::EnuConverter& converter,
                                  const Eigen::Vector3d& p_I_A,
                                  const OdometryDriftOptions& options) {
  if (!(options.half_window_s > 0.0)) {
    throw Error("RemoveOdometryDrift: half_window_s must be positive");
  }
  CheckIncreasing(fixes, "RemoveOdometryDrift: GNSS fix");
  const int64_t max_gap_ns = GapNsOrFromStamps(options.max_fix_gap_s, fixes, "max_fix_gap_s");
  // Pairs: keyframe index, time and fix minus antenna.
  std::vector<size_t> index;
  std::vector<int64_t> t_ns;
  std::vector<Eigen::Vector3d> d;
  for (size_t k = 0; k < keyframes->size(); ++k) {
    const Keyframe& kf = (*keyframes)[k];
    factors::GnssMeasurement m;
    if (!InterpolateSortedGnss(fixes, converter, kf.t_ns, max_gap_ns, &m)) continue;
    index.push_back(k);
    t_ns.push_back(kf.t_ns);
    d.push_back(m.p_W_A - (kf.p_W_I + kf.q_W_I * p_I_A));
  }
  OdometryDrift out;
  out.num_pairs = static_cast<int>(d.size());
  out.median_before_m = MedianDistance(d);
  // The correction at each keyframe whose window holds enough pairs.
  const int64_t half_ns = SecondsToNs(options.half_window_s);
  std::vector<std::optional<Eigen::Vector3d>> correction(keyframes->size());
  for (size_t k = 0; k < keyframes->size(); ++k) {
    const int64_t t = (*keyframes)[k].t_ns;
    const size_t begin =
        static_cast<size_t>(std::lower_bound(t_ns.begin(), t_ns.end(), t - half_ns) - t_ns.begin());
    const size_t end =
        static_cast<size_t>(std::upper_bound(t_ns.begin(), t_ns.end(), t + half_ns) - t_ns.begin());
    if (end - begin >= static_cast<size_t>(std::max(options.min_pairs, 2))) {
      correction[k] = LocalLineAt(t_ns, d, begin, end, t, options);
    }
  }
  if (!FillFromNearest(&correction)) {
    out.median_after_m = out.median_before_m;
    return out;
  }
  for (size_t k = 0; k < keyframes->size(); ++k) {
    (*keyframes)[k].p_W_I += *correction[k];
    out.max_correction_m = std::max(out.max_correction_m, correction[k]->norm());
  }
  for (size_t i = 0; i < d.size(); ++i) d[i] -= *correction[index[i]];
  out.median_after_m = MedianDistance(d);
  return out;
}

namespace {

// The antenna track around one keyframe (Eq. K7): position, velocity and the velocity's
// 1-sigma per horizontal axis from the fixes' sigmas and the fit's design (Eq. K10).
struct TrackFit {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  double velocity_sigma_m_s = 0.0;
};

// Eq. K10: the sigma of the linear coefficient b of a weighted least-squares quadratic, from
// the inliers' horizontal sigmas: sqrt([(sum_i x_i x_i^T / sigma_i^2)^-1]_bb),
// x_i = (1, tau_i, tau_i^2).
double VelocitySigma(const std::vector<double>& tau_s, const std::vector<double>& sigma_m,
                     const std::vector<size_t>& rows) {
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  for (size_t i : rows) {
    const Eigen::Vector3d x(1.0, tau_s[i], tau_s[i] * tau_s[i]);
    information += x * x.transpose() / (sigma_m[i] * sigma_m[i]);
  }
  const Eigen::Matrix3d covariance = information.inverse();
  return std::isfinite(covariance(1, 1)) && covariance(1, 1) > 0.0
             ? std::sqrt(covariance(1, 1))
             : std::numeric_limits<double>::infinity();
}

// Eq. K7: p(tau) = a + b tau + c tau^2 fitted to the fixes (tau from the keyframe time), each
// weighted by its horizontal sigma.
// Multipath jumps of metres would bend a least-squares quadratic towards them (several may
// fall in one window, one may sit at its end), so the fit starts from the least median of
// distances over quadratics through three fixes, one from each third of the window; fixes
// within the gate of that one are fitted by least squares, and the gate is re-applied.
// A fix within 3 of its own sigmas (floor_m) is never an outlier: with five to ten fixes the
// median distance can fall well below their noise, and the gate would then reject honest ones.
// False when fewer than min_fixes inliers remain or fewer than two on either side of tau = 0.
bool FitAntennaTrack(const std::vector<double>& tau_s, const std::vector<Eigen::Vector3d>& p,
                     const std::vector<double>& sigma_m, const std::vector<double>& floor_m,
                     const GnssPlacementOptions& o, TrackFit* track) {
  const size_t n = tau_s.size();
  if (n < static_cast<size_t>(std::max(o.min_fixes, 3))) return false;
  const auto basis = [&](size_t i) { return Eigen::Vector3d(1.0, tau_s[i], tau_s[i] * tau_s[i]); };
  std::vector<double> distance_m(n);
  const auto distances = [&](const Eigen::Matrix3d& coefficients) {
    for (size_t i = 0; i < n; ++i) distance_m[i] = (coefficients * basis(i) - p[i]).norm();
    return Median(distance_m);
  };
  // Weighted by the fixes' horizontal sigmas: the fit whose sigma Eq. K10 states.
  const auto solve = [&](const std::vector<size_t>& rows, Eigen::Matrix3d* coefficients) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero(), B = Eigen::Matrix3d::Zero();
    for (size_t i : rows) {
      const double w = 1.0 / (sigma_m[i] * sigma_m[i]);
      A += w * basis(i) * basis(i).transpose();
      B += w * basis(i) * p[i].transpose();
    }
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(A);
    if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) return false;
    *coefficients = ldlt.solve(B).transpose();
    return true;
  };

  // Least median of distances over three-fix quadratics, at most 5 fixes from each third,
  // spread over it: the stride rounds up (rounded down, 9 fixes a third took 9 and the last
  // third up to 11, 891 triples instead of 125).
  Eigen::Matrix3d coefficients = Eigen::Matrix3d::Zero();  // columns a, b, c
  double best_median = std::numeric_limits<double>::infinity();
  const size_t third = n / 3;
  const auto stride = [](size_t count) { return std::max<size_t>(1, (count + 4) / 5); };
  const size_t stride_first = stride(third), stride_last = stride(n - 2 * third);
  for (size_t i = 0; i < third; i += stride_first) {
    for (size_t j = third; j < 2 * third; j += stride_first) {
      for (size_t k = 2 * third; k < n; k += stride_last) {
        Eigen::Matrix3d candidate;
        if (!solve({i, j, k}, &candidate)) continue;
        const double median = distances(candidate);
        if (median < best_median) {
          best_median = median;
          coefficients = candidate;
        }
      }
    }
  }
  if (!std::isfinite(best_median)) return false;
  double median_m = best_median;
  std::vector<size_t> inliers, previous;
  for (int fit = 0; fit <= o.max_refits; ++fit) {
    const double gate_m = OutlierGate(median_m, o.min_outlier_distance_m, o.outlier_mad_factor);
    inliers.clear();
    int before = 0, after = 0;
    for (size_t i = 0; i < n; ++i) {
      if (distance_m[i] > std::max(gate_m, floor_m[i])) continue;
      inliers.push_back(i);
      before += tau_s[i] <= 0.0 ? 1 : 0;
      after += tau_s[i] >= 0.0 ? 1 : 0;
    }
    if (static_cast<int>(inliers.size()) < o.min_fixes || before < 2 || after < 2) return false;
    if (inliers == previous) break;
    if (!solve(inliers, &coefficients)) return false;
    median_m = distances(coefficients);
    previous = inliers;
  }
  track->position = coefficients.col(0);
  track->velocity = coefficients.col(1);
  track->velocity_sigma_m_s = VelocitySigma(tau_s, sigma_m, inliers);
  return true;
}

// The horizontal 1-sigma of a fix: the RMS of its east and north sigmas.
double HorizontalSigma(const sensors::GnssFix& fix) {
  return std::sqrt(0.5 *
                   (fix.std_enu_m.x() * fix.std_enu_m.x() + fix.std_enu_m.y() * fix.std_enu_m.y()));
}

// An angle's axis, as a difference in [-pi/2, pi/2]: a heading and its reverse alike.
double WrapAxis(double a) { return 0.5 * WrapAngle(2.0 * a); }

// Per heading, the axial mean (the doubled angles' circular mean, halved) of the headings
// flagged in `use` whose times lie within window_ns of its own; a heading without any keeps
// fallback's.
std::vector<double> LocalAxes(const std::vector<int64_t>& t_ns, const std::vector<double>& delta,
                              const std::vector<bool>& use, int64_t window_ns,
                              const std::vector<double>& fallback) {
  const size_t n = delta.size();
  std::vector<double> sin_sum(n + 1, 0.0), cos_sum(n + 1, 0.0);
  for (size_t i = 0; i < n; ++i) {
    sin_sum[i + 1] = sin_sum[i] + (use[i] ? std::sin(2.0 * delta[i]) : 0.0);
    cos_sum[i + 1] = cos_sum[i] + (use[i] ? std::cos(2.0 * delta[i]) : 0.0);
  }
  std::vector<double> axis(n);
  for (size_t j = 0; j < n; ++j) {
    const size_t lo = static_cast<size_t>(
        std::lower_bound(t_ns.begin(), t_ns.end(), t_ns[j] - window_ns) - t_ns.begin());
    const size_t hi = static_cast<size_t>(
        std::upper_bound(t_ns.begin(), t_ns.end(), t_ns[j] + window_ns) - t_ns.begin());
    const double s = sin_sum[hi] - sin_sum[lo], c = cos_sum[hi] - cos_sum[lo];
    axis[j] = s == 0.0 && c == 0.0 ? fallback[j] : 0.5 * std::atan2(s, c);
  }
  return axis;
}

// The headings (at times t_ns) within 0.2 rad of the axis of those around them, judged twice:
// the second time against the axes of the first time's inliers.
std::vector<bool> AxialInliers(const std::vector<int64_t>& t_ns, const std::vector<double>& delta,
                               int64_t window_ns, std::vector<double>* axis) {
  std::vector<bool> inlier(delta.size(), true);
  *axis = LocalAxes(t_ns, delta, inlier, window_ns, delta);
  for (int pass = 0; pass < 2; ++pass) {
    for (size_t j = 0; j < delta.size(); ++j) {
      inlier[j] = std::abs(WrapAxis(delta[j] - (*axis)[j])) <= 0.2;
    }
    if (pass == 0) *axis = LocalAxes(t_ns, delta, inlier, window_ns, *axis);
  }
  return inlier;
}

// Eq. K8 from the keyframes with a heading (their indices, times and the yaw each needs, delta).
// The gyro's yaw that turned the keyframes relative to each other drifts with its bias, so a
// heading is judged against those around it, not against one mean over the log: it is kept when
// within 0.2 rad of the axis (heading or its reverse) of those within window_ns, on the side of
// that axis, chained along the drive, that most of them take (a reversing vehicle's velocity
// points backwards). yaw_rad is the circular mean of the kept ones. Clears the flag
// (result->heading) of each keyframe left out: a reversing vehicle's, or an outlier's, which
// Eq. K9 would otherwise turn onto its velocity.
void YawFromHeadings(const std::vector<size_t>& index, const std::vector<int64_t>& t_ns,
                     const std::vector<double>& delta, int64_t window_ns, GnssPlacement* result) {
  std::vector<double> axis;
  const std::vector<bool> inlier = AxialInliers(t_ns, delta, window_ns, &axis);
  // The axis chained along the drive (steps between neighbours under pi/2), so that one side of
  // it is forward throughout; forward is the side most of the inliers take.
  std::vector<double> forward(delta.size());
  int ahead = 0, behind = 0;
  for (size_t j = 0; j < delta.size(); ++j) {
    forward[j] = j == 0 ? axis[0] : forward[j - 1] + WrapAxis(axis[j] - forward[j - 1]);
    if (!inlier[j]) continue;
    (std::abs(WrapAngle(delta[j] - forward[j])) < 0.5 * M_PI ? ahead : behind) += 1;
  }
  const double flip = behind > ahead ? M_PI : 0.0;
  double s = 0.0, c = 0.0, s_all = 0.0, c_all = 0.0, sum_rad2 = 0.0;
  result->num_headings = 0;
  for (size_t j = 0; j < delta.size(); ++j) {
    s_all += std::sin(delta[j]);
    c_all += std::cos(delta[j]);
    const double r = WrapAngle(delta[j] - forward[j] - flip);
    if (!inlier[j] || std::abs(r) > 0.5 * M_PI) {
      result->heading[index[j]] = false;
      continue;
    }
    s += std::sin(delta[j]);
    c += std::cos(delta[j]);
    sum_rad2 += r * r;
    ++result->num_headings;
  }
  // None kept (headings scattered beyond 0.2 rad everywhere): the circular mean of them all.
  result->yaw_rad = result->num_headings > 0 ? std::atan2(s, c) : std::atan2(s_all, c_all);
  result->heading_rms_rad = std::sqrt(sum_rad2 / std::max(1, result->num_headings));
}

// Eq. K11, the yaw from the track's geometry when too few keyframes move fast enough for a
// heading of their own: every placed keyframe's fitted velocity, turned into its forward
// frame (x along R_W_I R_I_V x) and weighted by its share of time, sums to the track's net
// travel along the vehicle's heading, d. Its direction is the yaw; its length must exceed
// max(min_track_travel_m, k sqrt(2) sigma) (the noise of a displacement between two fixes).
// Returns false when it does not, with the travel in *travel_m.
bool YawFromTrackGeometry(const std::vector<Keyframe>& kfs, const std::vector<bool>& placed,
                          const std::vector<TrackFit>& tracks, const Eigen::Quaterniond& q_I_V,
                          double needed_m, GnssPlacement* result, double* travel_m) {
  Eigen::Vector2d d = Eigen::Vector2d::Zero();
  for (size_t k = 0; k < kfs.size(); ++k) {
    if (!placed[k]) continue;
    const size_t prev = k == 0 ? k : k - 1, next = k + 1 == kfs.size() ? k : k + 1;
    const double dt_s = 0.5 * NsToSeconds(kfs[next].t_ns - kfs[prev].t_ns);
    d += Eigen::Rotation2Dd(-ForwardHeading(kfs[k], q_I_V)) * tracks[k].velocity.head<2>() * dt_s;
  }
  *travel_m = d.norm();
  if (!(*travel_m >= needed_m)) return false;
  result->yaw_rad = std::atan2(d.y(), d.x());
  result->yaw_from_track_geometry = true;
  return true;
}

// The median of the fixes' horizontal sigmas.
double MedianHorizontalSigma(const sensors::GnssFixes& fixes) {
  std::vector<double> sigma_m;
  sigma_m.reserve(fixes.size());
  for (const sensors::GnssFix& fix : fixes) sigma_m.push_back(HorizontalSigma(fix));
  return Median(sigma_m);
}

// Keyframes without a track of their own: between the nearest placed ones (or moved with the
// nearest one's velocity at the ends), found by one pass each way (an outage of m keyframes
// scanned outwards from each took m^2 steps).
void BridgeUnplaced(const std::vector<Keyframe>& kfs, const std::vector<bool>& placed,
                    std::vector<TrackFit>* tracks, int* num_bridged) {
  std::vector<TrackFit>& t = *tracks;
  const std::vector<std::optional<size_t>> before = NearestFlagged(placed, +1);
  const std::vector<std::optional<size_t>> after = NearestFlagged(placed, -1);
  for (size_t k = 0; k < kfs.size(); ++k) {
    if (placed[k]) continue;
    const auto from = [&](size_t j) {
      t[k].position = t[j].position + t[j].velocity * NsToSeconds(kfs[k].t_ns - kfs[j].t_ns);
      t[k].velocity = t[j].velocity;
    };
    if (!before[k]) {
      from(*after[k]);
    } else if (!after[k]) {
      from(*before[k]);
    } else {
      const size_t i = *before[k], j = *after[k];
      const double s =
          NsToSeconds(kfs[k].t_ns - kfs[i].t_ns) / NsToSeconds(kfs[j].t_ns - kfs[i].t_ns);
      t[k].position = (1.0 - s) * t[i].position + s * t[j].position;
      t[k].velocity = (1.0 - s) * t[i].velocity + s * t[j].velocity;
    }
    ++*num_bridged;
  }
}

// Eq. K7 around every keyframe: the fixes within half_width_s, with their sigmas (K10) and
// the outlier floor of 3 of their own sigmas. placed[k] says whether keyframe k got a track.
std::vector<TrackFit> FitTracks(const std::vector<Keyframe>& kfs, const sensors::GnssFixes& fixes,
                                const sensors::EnuConverter& converter,
                                const GnssPlacementOptions& options, std::vector<bool>* placed) {
  std::vector<Eigen::Vector3d> fixes_W(fixes.size());
  for (size_t i = 0; i < fixes.size(); ++i) fixes_W[i] = converter.ToEnu(fixes[i]);
  const int64_t half_width_ns = SecondsToNs(options.half_width_s);
  std::vector<TrackFit> tracks(kfs.size());
  placed->assign(kfs.size(), false);
  for (size_t k = 0; k < kfs.size(); ++k) {
    const int64_t t_ns = kfs[k].t_ns;
    auto it = std::lower_bound(fixes.begin(), fixes.end(), t_ns - half_width_ns,
                               [](const sensors::GnssFix& f, int64_t t) { return f.t_ns < t; });
    std::vector<double> tau_s, sigma_m, floor_m;
    std::vector<Eigen::Vector3d> p;
    for (; it != fixes.end() && it->t_ns <= t_ns + half_width_ns; ++it) {
      tau_s.push_back(NsToSeconds(it->t_ns - t_ns));
      p.push_back(fixes_W[static_cast<size_t>(it - fixes.begin())]);
      sigma_m.push_back(HorizontalSigma(*it));
      floor_m.push_back(3.0 * it->std_enu_m.norm());
    }
    (*placed)[k] = FitAntennaTrack(tau_s, p, sigma_m, floor_m, options, &tracks[k]);
  }
  return tracks;
}

// The yaw each keyframe whose speed stands out of its velocity's noise (Eq. K10) needs
// (Eq. K8), flagged in *heading; and, for messages, the keyframe whose speed stands out most.
struct Headings {
  std::vector<size_t> index;  // of the flagged keyframes, in time order
  std::vector<int64_t> t_ns;
  std::vector<double> delta_rad;
  double best_speed_m_s = 0.0;
  double best_sigma_m_s = 0.0;
};
Headings TrustedHeadings(const std::vector<Keyframe>& kfs, const std::vector<bool>& placed,
                         const std::vector<TrackFit>& tracks, const Eigen::Quaterniond& q_I_V,
                         double heading_sigmas, std::vector<bool>* heading) {
  Headings h;
  double best_ratio = 0.0;
  heading->assign(kfs.size(), false);
  for (size_t k = 0; k < kfs.size(); ++k) {
    if (!placed[k]) continue;
    const Eigen::Vector3d& v = tracks[k].velocity;
    const double ratio = v.head<2>().norm() / tracks[k].velocity_sigma_m_s;
    if (ratio > best_ratio) {
      best_ratio = ratio;
      h.best_speed_m_s = v.head<2>().norm();
      h.best_sigma_m_s = tracks[k].velocity_sigma_m_s;
    }
    if (!(ratio > heading_sigmas)) continue;
    (*heading)[k] = true;
    h.index.push_back(k);
    h.t_ns.push_back(kfs[k].t_ns);
    h.delta_rad.push_back(WrapAngle(std::atan2(v.y(), v.x()) - ForwardHeading(kfs[k], q_I_V)));
  }
  return h;
}

// Neither the headings nor the track's travel give the yaw: why, with the figures.
[[noreturn]] void ThrowNoYaw(const Headings& h, int num_placed, const GnssPlacementOptions& o,
                             double travel_m, double needed_m, double sigma_m) {
  throw Error(
      "PlaceKeyframesOnGnss: no heading for the yaw: " + std::to_string(h.delta_rad.size()) +
      " of " + std::to_string(num_placed) + " keyframes on the GNSS track move faster than " +
      FormatFixed(o.heading_sigmas, 1) + " sigma of their fitted velocity (" +
      std::to_string(o.min_headings) + " needed; the best: " + FormatFixed(h.best_speed_m_s, 2) +
      " m/s against a sigma of " + FormatFixed(h.best_sigma_m_s, 2) + " m/s from " +
      FormatFixed(o.half_width_s, 1) + " s of fixes on either side), and the track travels " +
      FormatFixed(travel_m, 1) + " m net along the vehicle's heading, less than the " +
      FormatFixed(needed_m, 1) + " m needed (the fixes' median horizontal sigma is " +
      FormatFixed(sigma_m, 2) + " m): the drive is too slow or too short to tell where the " +
      "vehicle points");
}

// The options with the track's half-width set: 0 takes Eq. T3 from the fixes' stamps (its floor,
// 1 s, for fewer than two fixes, which place nothing).
GnssPlacementOptions WithTrackHalfWidth(GnssPlacementOptions options,
                                        const sensors::GnssFixes& fixes) {
  if (options.half_width_s != 0.0) return options;
  options.half_width_s = fixes.size() < 2 ? 1.0
                                          : sensors::GnssTrackHalfWidthS(sensors::MeasureTiming(
                                                sensors::StampsOf(fixes), "GNSS fix"));
  return options;
}

}  // namespace

GnssPlacement PlaceKeyframesOnGnss(std::vector<Keyframe>* keyframes,
                                   const sensors::GnssFixes& fixes,
                                   const sensors::EnuConverter& converter,
                                   const Eigen::Vector3d& p_I_A, const Eigen::Quaterniond& q_I_V,
                                   const GnssPlacementOptions& given) {
  CheckIncreasing(fixes, "PlaceKeyframesOnGnss: GNSS fix");
  if (!(given.half_width_s >= 0.0) || given.min_fixes < 3 || given.max_refits < 0 ||
      !(given.heading_sigmas > 0.0) || given.min_headings < 1 || !(given.heading_window_s > 0.0)) {
    throw Error(
        "PlaceKeyframesOnGnss: half_width_s must not be negative (0: from the fixes' rate), "
        "heading_sigmas and heading_window_s must be positive, min_fixes at least 3, "
        "min_headings at least 1 and max_refits not negative");
  }
  const GnssPlacementOptions options = WithTrackHalfWidth(given, fixes);
  std::vector<Keyframe>& kfs = *keyframes;
  GnssPlacement result;
  const std::vector<bool>& placed = result.placed;
  std::vector<TrackFit> tracks = FitTracks(kfs, fixes, converter, options, &result.placed);
  result.num_placed = static_cast<int>(std::count(placed.begin(), placed.end(), true));
  if (result.num_placed < 2) {
    throw Error("PlaceKeyframesOnGnss: only " + std::to_string(result.num_placed) + " of " +
                std::to_string(kfs.size()) + " keyframes have a GNSS track around them");
  }

  // Eq. K8 on the keyframes with a trusted heading, else Eq. K11 on the whole track.
  const Headings headings =
      TrustedHeadings(kfs, placed, tracks, q_I_V, options.heading_sigmas, &result.heading);
  if (static_cast<int>(headings.delta_rad.size()) >= options.min_headings) {
    YawFromHeadings(headings.index, headings.t_ns, headings.delta_rad,
                    SecondsToNs(options.heading_window_s), &result);
  } else {
    const double sigma_m = MedianHorizontalSigma(fixes);
    const double needed_m =
        std::max(options.min_track_travel_m, options.heading_sigmas * std::sqrt(2.0) * sigma_m);
    double travel_m = 0.0;
    if (!YawFromTrackGeometry(kfs, placed, tracks, q_I_V, needed_m, &result, &travel_m)) {
      ThrowNoYaw(headings, result.num_placed, options, travel_m, needed_m, sigma_m);
    }
    result.heading.assign(kfs.size(), false);
  }

  result.velocity_sigma_m_s.resize(kfs.size());
  for (size_t k = 0; k < kfs.size(); ++k) {
    result.velocity_sigma_m_s[k] =
        placed[k] ? tracks[k].velocity_sigma_m_s : std::numeric_limits<double>::infinity();
  }
  BridgeUnplaced(kfs, placed, &tracks, &result.num_bridged);
  const Eigen::Quaterniond q_z(Eigen::AngleAxisd(result.yaw_rad, Eigen::Vector3d::UnitZ()));
  for (size_t k = 0; k < kfs.size(); ++k) {
    Keyframe& kf = kfs[k];
    kf.q_W_I = (q_z * kf.q_W_I).normalized();
    kf.p_W_I = tracks[k].position - kf.q_W_I * p_I_A;
    kf.v_W_I = tracks[k].velocity;
  }
  return result;
}

}  // namespace estimation
}  // namespace autocal
