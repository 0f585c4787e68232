// Keyframes moved onto GNSS (docs/keyframe_factors.md, "Keyframes from GNSS"): a rigid yaw and
// translation of a whole trajectory onto the fixes (Eqs. K3-K5), and each keyframe placed on a
// local quadratic fit of the antenna track (Eq. K7).
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "estimation/keyframe_interpolation.h"

namespace autocal {
namespace estimation {
namespace {

using internal::CheckIncreasing;
using internal::GapNs;
using internal::InterpolateSortedGnss;

// The middle element of `values` (the upper one for an even count).
double Median(std::vector<double> values) {
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

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

// Eq. K7: p(tau) = a + b tau + c tau^2 fitted to the fixes (tau from the keyframe time).
// Multipath jumps of metres would bend a least-squares quadratic towards them (several may
// fall in one window, one may sit at its end), so the fit starts from the least median of
// distances over quadratics through three fixes, one from each third of the window; fixes
// within the gate of that one are fitted by least squares, and the gate is re-applied.
// False when fewer than min_fixes inliers remain or fewer than two on either side of tau = 0.
bool FitAntennaTrack(const std::vector<double>& tau_s, const std::vector<Eigen::Vector3d>& p,
                     const GnssPlacementOptions& o, Eigen::Vector3d* position,
                     Eigen::Vector3d* velocity) {
  const size_t n = tau_s.size();
  if (n < static_cast<size_t>(std::max(o.min_fixes, 3))) return false;
  const auto basis = [&](size_t i) { return Eigen::Vector3d(1.0, tau_s[i], tau_s[i] * tau_s[i]); };
  std::vector<double> distance_m(n);
  const auto distances = [&](const Eigen::Matrix3d& coefficients) {
    for (size_t i = 0; i < n; ++i) distance_m[i] = (coefficients * basis(i) - p[i]).norm();
    return Median(distance_m);
  };
  const auto solve = [&](const std::vector<size_t>& rows, Eigen::Matrix3d* coefficients) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero(), B = Eigen::Matrix3d::Zero();
    for (size_t i : rows) {
      A += basis(i) * basis(i).transpose();
      B += basis(i) * p[i].transpose();
    }
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(A);
    if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) return false;
    *coefficients = ldlt.solve(B).transpose();
    return true;
  };

  // Least median of distances over three-fix quadratics (at most 5 fixes per third).
  Eigen::Matrix3d coefficients = Eigen::Matrix3d::Zero();  // columns a, b, c
  double best_median = std::numeric_limits<double>::infinity();
  const size_t third = n / 3;
  const size_t stride = std::max<size_t>(1, third / 5);
  for (size_t i = 0; i < third; i += stride) {
    for (size_t j = third; j < 2 * third; j += stride) {
      for (size_t k = 2 * third; k < n; k += stride) {
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
      if (distance_m[i] > gate_m) continue;
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
  *position = coefficients.col(0);
  *velocity = coefficients.col(1);
  return true;
}

double WrapAngle(double a) { return std::atan2(std::sin(a), std::cos(a)); }

}  // namespace

GnssPlacement PlaceKeyframesOnGnss(std::vector<Keyframe>* keyframes,
                                   const sensors::GnssFixes& fixes,
                                   const sensors::EnuConverter& converter,
                                   const Eigen::Vector3d& p_I_A, const Eigen::Quaterniond& q_I_V,
                                   const GnssPlacementOptions& options) {
  CheckIncreasing(fixes, "PlaceKeyframesOnGnss: GNSS fix");
  if (!(options.half_width_s > 0.0) || options.min_fixes < 3 || options.max_refits < 0) {
    throw Error(
        "PlaceKeyframesOnGnss: half_width_s must be positive, min_fixes at least 3 and "
        "max_refits not negative");
  }
  std::vector<Eigen::Vector3d> fixes_W(fixes.size());
  for (size_t i = 0; i < fixes.size(); ++i) fixes_W[i] = converter.ToEnu(fixes[i]);
  const int64_t half_width_ns = SecondsToNs(options.half_width_s);

  // Eq. K7 around every keyframe.
  std::vector<Keyframe>& kfs = *keyframes;
  GnssPlacement result;
  std::vector<bool>& placed = result.placed;
  placed.assign(kfs.size(), false);
  std::vector<Eigen::Vector3d> p_W_A(kfs.size()), v_W_A(kfs.size());
  for (size_t k = 0; k < kfs.size(); ++k) {
    const int64_t t_ns = kfs[k].t_ns;
    auto it = std::lower_bound(fixes.begin(), fixes.end(), t_ns - half_width_ns,
                               [](const sensors::GnssFix& f, int64_t t) { return f.t_ns < t; });
    std::vector<double> tau_s;
    std::vector<Eigen::Vector3d> p;
    for (; it != fixes.end() && it->t_ns <= t_ns + half_width_ns; ++it) {
      tau_s.push_back(NsToSeconds(it->t_ns - t_ns));
      p.push_back(fixes_W[static_cast<size_t>(it - fixes.begin())]);
    }
    placed[k] = FitAntennaTrack(tau_s, p, options, &p_W_A[k], &v_W_A[k]);
    result.num_placed += placed[k] ? 1 : 0;
  }
  if (result.num_placed < 2) {
    throw Error("PlaceKeyframesOnGnss: only " + std::to_string(result.num_placed) + " of " +
                std::to_string(kfs.size()) + " keyframes have a GNSS track around them");
  }

  // Eq. K8: the yaw that turns the vehicle's forward axis onto the track heading (circular
  // mean, then once more without headings over 0.2 rad from it: reversing, slip, bad fits).
  std::vector<double> delta;
  for (size_t k = 0; k < kfs.size(); ++k) {
    if (!placed[k] || v_W_A[k].head<2>().norm() < options.min_heading_speed_m_s) continue;
    const Eigen::Vector3d forward_W = kfs[k].q_W_I * (q_I_V * Eigen::Vector3d::UnitX());
    delta.push_back(WrapAngle(std::atan2(v_W_A[k].y(), v_W_A[k].x()) -
                              std::atan2(forward_W.y(), forward_W.x())));
  }
  if (delta.empty()) {
    throw Error("PlaceKeyframesOnGnss: the GNSS track is never faster than " +
                std::to_string(options.min_heading_speed_m_s) + " m/s: no heading for the yaw");
  }
  const auto circular_mean = [&](double center, double gate) {
    double s = 0.0, c = 0.0;
    int n = 0;
    for (double d : delta) {
      if (std::abs(WrapAngle(d - center)) > gate) continue;
      s += std::sin(d);
      c += std::cos(d);
      ++n;
    }
    return n > 0 ? std::atan2(s, c) : center;
  };
  result.yaw_rad = circular_mean(circular_mean(0.0, M_PI + 1.0), 0.2);
  double sum_rad2 = 0.0;
  for (double d : delta) {
    const double r = WrapAngle(d - result.yaw_rad);
    if (std::abs(r) > 0.2) continue;
    sum_rad2 += r * r;
    ++result.num_headings;
  }
  result.heading_rms_rad = std::sqrt(sum_rad2 / std::max(1, result.num_headings));

  // Keyframes without a track of their own: between placed neighbours.
  for (size_t k = 0; k < kfs.size(); ++k) {
    if (placed[k]) continue;
    ptrdiff_t before = static_cast<ptrdiff_t>(k) - 1, after = static_cast<ptrdiff_t>(k) + 1;
    while (before >= 0 && !placed[static_cast<size_t>(before)]) --before;
    while (after < static_cast<ptrdiff_t>(kfs.size()) && !placed[static_cast<size_t>(after)]) {
      ++after;
    }
    const auto from = [&](size_t j) {
      p_W_A[k] = p_W_A[j] + v_W_A[j] * NsToSeconds(kfs[k].t_ns - kfs[j].t_ns);
      v_W_A[k] = v_W_A[j];
    };
    if (before < 0) {
      from(static_cast<size_t>(after));
    } else if (after >= static_cast<ptrdiff_t>(kfs.size())) {
      from(static_cast<size_t>(before));
    } else {
      const size_t i = static_cast<size_t>(before), j = static_cast<size_t>(after);
      const double s =
          NsToSeconds(kfs[k].t_ns - kfs[i].t_ns) / NsToSeconds(kfs[j].t_ns - kfs[i].t_ns);
      p_W_A[k] = (1.0 - s) * p_W_A[i] + s * p_W_A[j];
      v_W_A[k] = (1.0 - s) * v_W_A[i] + s * v_W_A[j];
    }
    ++result.num_bridged;
  }

  const Eigen::Quaterniond q_z(Eigen::AngleAxisd(result.yaw_rad, Eigen::Vector3d::UnitZ()));
  for (size_t k = 0; k < kfs.size(); ++k) {
    Keyframe& kf = kfs[k];
    kf.q_W_I = (q_z * kf.q_W_I).normalized();
    kf.p_W_I = p_W_A[k] - kf.q_W_I * p_I_A;
    kf.v_W_I = v_W_A[k];
  }
  return result;
}

}  // namespace estimation
}  // namespace autocal
