#include "autocal/estimation/calibration_initializer.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/estimation/lidar_inertial_batch.h"
#include "autocal/geometry/so3.h"
#include "autocal/sensors/imu_preintegration.h"
#include "estimation/inertial_fit.h"

namespace autocal {
namespace estimation {

namespace {

using internal::InertialFit;
using internal::KeyframeSlot;

std::string Format(double value, int precision = 3) {
  std::ostringstream s;
  s.precision(precision);
  s << value;
  return s.str();
}

// T_O_L at LiDAR time t_ns, interpolated on SE(3) between the odometry poses around it (or
// extrapolated with the nearest interval's twist): T_a Exp(s Log(T_a^-1 T_b)).
geometry::Pose3d PoseAt(const std::vector<lidar::OdometryFrame>& frames, int64_t t_ns) {
  auto it = std::upper_bound(frames.begin(), frames.end(), t_ns,
                             [](int64_t t, const lidar::OdometryFrame& f) { return t < f.t_ns; });
  std::ptrdiff_t b = std::clamp<std::ptrdiff_t>(it - frames.begin(), 1,
                                                static_cast<std::ptrdiff_t>(frames.size()) - 1);
  const lidar::OdometryFrame& fa = frames[static_cast<size_t>(b - 1)];
  const lidar::OdometryFrame& fb = frames[static_cast<size_t>(b)];
  const double s = SecondsBetween(fa.t_ns, t_ns) / SecondsBetween(fa.t_ns, fb.t_ns);
  const geometry::Vector6<double> xi = geometry::LogSE3(fa.T_W_L.Inverse() * fb.T_W_L);
  return fa.T_W_L * geometry::ExpSE3(geometry::Vector6<double>(s * xi));
}

// The mean gyro rate (bias removed) over IMU times [t0_ns, t1_ns]; zero when no sample
// falls inside.
Eigen::Vector3d MeanRate(const sensors::ImuSamples& imu, const Eigen::Vector3d& bias, int64_t t0_ns,
                         int64_t t1_ns) {
  const sensors::GyroMean mean = sensors::MeanGyro(imu, t0_ns, t1_ns);
  return mean.samples == 0 ? Eigen::Vector3d::Zero() : Eigen::Vector3d(mean.rate_rad_s - bias);
}

// Step 1 (and its repetition). With `gyro` set, each sweep is deskewed with the gyro rate
// over the sweep rotated into L, R_I_L^T (w - b_g), at the estimated offset (eq. I2). Returns false
// (with a problem) when a registration fails.
struct GyroDeskew {
  Eigen::Quaterniond q_I_L;
  double offset_s = 0.0;
  Eigen::Vector3d gyro_bias_rad_s;
};

// A sweep's stamp and the times of its first and last points, recorded while the odometry
// reads it.
struct SweepTimes {
  int64_t t_ns = 0;
  SweepSpan span;
};

// Appends sweep k's times; throws autocal::Error when its stamp does not follow the last.
void AppendSweepTimes(const lidar::LidarSweep& sweep, size_t k, std::vector<SweepTimes>* times) {
  if (!times->empty() && sweep.t_ns <= times->back().t_ns) {
    throw Error("InitializeLidarImu: sweep stamps must increase (sweep " + std::to_string(k) + ")");
  }
  times->push_back({sweep.t_ns, SpanOf(sweep)});
}

bool RunOdometry(const sensors::ImuSamples& imu, lidar::SweepSource* sweeps,
                 const lidar::LidarOdometryOptions& setting, const std::optional<GyroDeskew>& gyro,
                 CalibrationInitialization* out, std::vector<SweepTimes>* times,
                 size_t* failed_sweep) {
  lidar::LidarOdometry odometry(setting);
  times->clear();
  for (size_t k = 0; k < sweeps->size(); ++k) {
    const lidar::LidarSweep& sweep = sweeps->Sweep(k);
    AppendSweepTimes(sweep, k, times);
    std::optional<Eigen::Vector3d> rate_L;
    if (gyro) {
      // Over the points' span, which a sweep stamped at its end has before its stamp.
      const ImuInterval points = SweepImuInterval(sweep.t_ns, times->back().span, gyro->offset_s);
      rate_L = gyro->q_I_L.conjugate() *
               MeanRate(imu, gyro->gyro_bias_rad_s, points.begin_ns, points.end_ns);
    }
    try {
      odometry.AddSweep(sweep, rate_L);
    } catch (const Error& e) {
      // The stamp names the sweep in the log also when the caller passed every n-th sweep.
      out->problems.push_back("LiDAR odometry failed at sweep " + std::to_string(k) + " of " +
                              std::to_string(sweeps->size()) + " (stamp " +
                              std::to_string(sweep.t_ns) + " ns, " +
                              Format(NsToSeconds(sweep.t_ns - times->front().t_ns)) +
                              " s after the first): " + e.what());
      *failed_sweep = k;
      return false;
    }
  }
  out->odometry = odometry.frames();
  int weak = 0;
  for (const lidar::OdometryFrame& frame : out->odometry) {
    weak += !frame.icp.weak_translations.empty() || !frame.icp.weak_rotation_axes.empty();
  }
  if (weak > 0) {
    out->fallbacks.push_back(
        "LiDAR odometry: " + std::to_string(weak) + " of " + std::to_string(sweeps->size()) +
        " sweeps had a direction of motion that few correspondences constrain (a corridor, a "
        "tunnel, a road between barriers: fewer than 1 in 200 look along it); their motion "
        "along it rests on those few");
  }
  return true;
}

// Step 2.
void FindRestPeriod(const sensors::ImuSamples& imu, const CalibrationInitializerOptions& options,
                    CalibrationInitialization* out) {
  out->still_start = DetectStillStart(imu, options.still_start);
  if (out->still_start.found) return;
  const StillStart quiet = DetectStillStart(imu, options.low_excitation);
  if (quiet.found) {
    out->still_start = quiet;
    out->still_start_is_low_excitation = true;
    return;
  }
  out->problems.push_back(
      "no still start (" + out->still_start.reason + ") and no low-excitation period (" +
      quiet.reason +
      "): the gyro bias and the direction of gravity are unknown; start the log with the "
      "vehicle at rest for at least " +
      Format(options.still_start.min_duration_s) + " s");
}

// Step 3.
void EstimateOffset(const sensors::ImuSamples& imu, const CalibrationInitializerOptions& options,
                    CalibrationInitialization* out) {
  const auto& frames = out->odometry;
  for (size_t k = 1; k < frames.size(); ++k) {
    RelativeRotation r;
    r.t0_ns = frames[k - 1].t_ns;
    r.t1_ns = frames[k].t_ns;
    r.q_0_1 = frames[k - 1].T_W_L.q.conjugate() * frames[k].T_W_L.q;
    out->sweep_rotations.push_back(r);
  }
  out->time_offset = EstimateTimeOffset(out->sweep_rotations, imu, out->still_start.gyro_bias_rad_s,
                                        options.time_offset);
  if (!out->time_offset.reliable) {
    const std::string why =
        "the LiDAR-IMU time offset is not determined: " + out->time_offset.reason;
    if (options.fallback_time_offset_s) {
      out->time_offset.offset_s = *options.fallback_time_offset_s;
      out->fallbacks.push_back(why + "; the given " +
                               Format(*options.fallback_time_offset_s * 1e3) + " ms is used");
    } else {
      out->problems.push_back(why);
    }
  }
}

// Step 4: hand-eye pairs about hand_eye_pair_spacing_s long (eq. I1).
void SolveRotation(const sensors::ImuSamples& imu, const CalibrationInitializerOptions& options,
                   CalibrationInitialization* out) {
  const auto& frames = out->odometry;
  const int64_t offset_ns = SecondsToNs(out->time_offset.offset_s);
  const int64_t spacing_ns = SecondsToNs(options.hand_eye_pair_spacing_s);
  int rotating = 0;
  for (size_t a = 0, b = 0; a < frames.size(); ++a) {
    b = std::max(b, a + 1);
    while (b < frames.size() && frames[b].t_ns < frames[a].t_ns + spacing_ns) ++b;
    if (b >= frames.size()) break;
    const int64_t t0 = frames[a].t_ns + offset_ns, t1 = frames[b].t_ns + offset_ns;
    if (t0 < imu.front().t_ns || t1 > imu.back().t_ns) continue;
    const Eigen::Quaterniond q_L = frames[a].T_W_L.q.conjugate() * frames[b].T_W_L.q;
    out->hand_eye_lidar_rotations.push_back(q_L);
    out->hand_eye_imu_rotations.push_back(
        IntegrateGyro(imu, out->still_start.gyro_bias_rad_s, t0, t1));
    if (geometry::AngleOf(q_L) * kRadToDeg >= options.min_pair_rotation_deg) ++rotating;
  }
  std::string why;
  if (rotating < options.min_rotating_pairs) {
    why = "too little rotation for the hand-eye rotation: " + std::to_string(rotating) + " of " +
          std::to_string(out->hand_eye_lidar_rotations.size()) + " intervals of " +
          Format(options.hand_eye_pair_spacing_s) + " s turned more than " +
          Format(options.min_pair_rotation_deg) + " deg (need " +
          std::to_string(options.min_rotating_pairs) + "); the drive needs turns";
  } else {
    out->rotation = SolveHandEyeRotation(out->hand_eye_imu_rotations, out->hand_eye_lidar_rotations,
                                         options.hand_eye);
    if (!out->rotation.observable) {
      why = "the LiDAR-IMU rotation is not determined: " + out->rotation.reason;
    }
  }
  if (why.empty()) return;
  if (options.fallback_q_I_L) {
    out->rotation.observable = false;
    out->rotation.reason = why;
    out->rotation.q_I_L = *options.fallback_q_I_L;
    out->fallbacks.push_back(why + "; the given rotation is used");
  } else {
    out->problems.push_back(why);
  }
}

// The keyframes of steps 5 and 6 (internal::KeyframeSlot): one per sweep whose points, with its
// reference instant (point time 0) and the offset margin at each end, lie inside the IMU log.
std::vector<KeyframeSlot> KeyframeSlots(const sensors::ImuSamples& imu,
                                        const std::vector<SweepTimes>& sweeps,
                                        const CalibrationInitializerOptions& options,
                                        CalibrationInitialization* out_ptr) {
  const CalibrationInitialization& out = *out_ptr;
  const double offset_s = out.time_offset.offset_s;
  const int64_t offset_ns = SecondsToNs(offset_s);
  std::vector<KeyframeSlot> slots;
  const int64_t margin_ns = SecondsToNs(options.offset_margin_s);
  for (size_t k = 0; k < sweeps.size(); ++k) {
    const SweepTimes& sweep = sweeps[k];
    const int64_t t_ns = KeyframeTime(sweep.t_ns, sweep.span, offset_s);
    const ImuInterval points = SweepImuInterval(sweep.t_ns, sweep.span, offset_s);
    if (points.begin_ns - margin_ns < imu.front().t_ns ||
        points.end_ns + margin_ns > imu.back().t_ns) {
      continue;
    }
    // Sweeps whose points span differently (a truncated one) could bring a keyframe close to
    // the last: the IMU factor between them needs an interval.
    if (!slots.empty() && t_ns - slots.back().t_ns < SecondsToNs(options.min_keyframe_interval_s)) {
      continue;
    }
    // Nor an interval without an IMU sample (a dropout): its covariance would be singular.
    if (!slots.empty() && !sensors::ImuSampleBetween(imu, slots.back().t_ns, t_ns)) {
      ++out_ptr->keyframes_in_imu_dropouts;
      continue;
    }
    slots.push_back({static_cast<int>(k), t_ns, PoseAt(out.odometry, t_ns - offset_ns)});
  }
  return slots;
}

// The IMU's rotation R_I(from)_I(to) from gyro integration, in either direction: the first
// keyframe lies inside the rest period when the LiDAR starts during it, and after its end
// when the IMU starts recording well before the LiDAR.
Eigen::Quaterniond GyroRotation(const sensors::ImuSamples& imu, const Eigen::Vector3d& b_g,
                                int64_t from_ns, int64_t to_ns) {
  if (to_ns >= from_ns) return IntegrateGyro(imu, b_g, from_ns, to_ns);
  return IntegrateGyro(imu, b_g, to_ns, from_ns).conjugate();
}

// Step 6: W is O rotated so that gravity points along -z and the first keyframe's yaw is
// zero, with its origin at the first keyframe's IMU position.
geometry::Pose3d GravityAlignedWorld(const Eigen::Vector3d& g_O, const Eigen::Matrix3d& R_O_I_0,
                                     const Eigen::Vector3d& p_O_I_0) {
  const Eigen::Quaterniond q_tilt =
      Eigen::Quaterniond::FromTwoVectors(-g_O, Eigen::Vector3d::UnitZ());
  const Eigen::Matrix3d R = q_tilt * R_O_I_0;
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  const Eigen::Quaterniond q_W_O =
      (Eigen::AngleAxisd(-yaw, Eigen::Vector3d::UnitZ()) * q_tilt).normalized();
  return geometry::Pose3d(q_W_O, -(q_W_O * p_O_I_0));
}

}  // namespace

namespace {

void CheckImuStamps(const sensors::ImuSamples& imu) {
  for (size_t i = 1; i < imu.size(); ++i) {
    if (imu[i].t_ns <= imu[i - 1].t_ns) {
      throw Error("InitializeLidarImu: IMU stamps must increase (sample " + std::to_string(i) +
                  ")");
    }
  }
}

bool TooShort(const sensors::ImuSamples& imu, size_t num_sweeps, CalibrationInitialization* out) {
  if (imu.size() >= 2 && num_sweeps >= 2) return false;
  out->problems.push_back("the log holds " + std::to_string(imu.size()) + " IMU samples and " +
                          std::to_string(num_sweeps) + " sweeps: too short to initialize");
  return true;
}

// Steps 5 and 6 on out's odometry, rest period, offset and rotation.
void AlignAndBuildKeyframes(const sensors::ImuSamples& imu, const std::vector<SweepTimes>& sweeps,
                            const CalibrationInitializerOptions& options,
                            CalibrationInitialization* out_ptr);

}  // namespace

CalibrationInitializerOptions RefinedLaterInitializerOptions() {
  CalibrationInitializerOptions o;
  o.odometry.voxel_m = 0.4;
  o.odometry.registration_voxel_m = 1.0;
  o.odometry.icp.convergence.translation_m = 1e-3;
  o.odometry.icp.convergence.rotation_rad = 1e-4;
  o.gyro_deskew_pass = false;
  return o;
}

CalibrationInitialization InitializeLidarImu(const sensors::ImuSamples& imu,
                                             const std::vector<lidar::LidarSweep>& sweeps,
                                             const CalibrationInitializerOptions& options) {
  lidar::SweepVector source(sweeps);
  return InitializeLidarImu(imu, &source, options);
}

CalibrationInitialization InitializeLidarImu(const sensors::ImuSamples& imu,
                                             lidar::SweepSource* sweeps,
                                             const CalibrationInitializerOptions& options) {
  CheckImuStamps(imu);
  CalibrationInitialization out;
  if (TooShort(imu, sweeps->size(), &out)) return out;
  // A long enough log before a stretch the odometry cannot follow (a featureless road) still
  // initializes: the chain runs again on the sweeps before it.
  size_t failed_sweep = 0;
  const auto on_sweeps_before_failure = [&]() {
    if (failed_sweep < 2 ||
        static_cast<double>(failed_sweep) <
            options.min_odometry_fraction * static_cast<double>(sweeps->size())) {
      return out;
    }
    const std::string why = out.problems.back();
    lidar::SweepPrefix before_failure(sweeps, failed_sweep);
    CalibrationInitialization prefix = InitializeLidarImu(imu, &before_failure, options);
    prefix.fallbacks.insert(prefix.fallbacks.begin(), why + "; the sweeps before it are used");
    return prefix;
  };
  lidar::LidarOdometryOptions first_pass = options.odometry;
  if (options.gyro_deskew_pass) {
    first_pass.registration_voxel_m =
        std::max(first_pass.registration_voxel_m, options.first_pass_registration_voxel_m);
  }
  std::vector<SweepTimes> times;
  if (!RunOdometry(imu, sweeps, first_pass, std::nullopt, &out, &times, &failed_sweep)) {
    return on_sweeps_before_failure();
  }
  FindRestPeriod(imu, options, &out);
  // The later steps also run without a rest period (zero gyro bias) so that every problem of
  // a poor log is reported at once.
  EstimateOffset(imu, options, &out);
  SolveRotation(imu, options, &out);
  if (!out.problems.empty()) return out;
  if (options.gyro_deskew_pass) {
    // Constant-velocity deskewing lets the odometry lag when the turn rate changes; with the
    // rotation and offset known roughly, the gyro deskews each sweep and steps 3-4 repeat.
    const GyroDeskew gyro{out.rotation.q_I_L, out.time_offset.offset_s,
                          out.still_start.gyro_bias_rad_s};
    out.sweep_rotations.clear();
    out.fallbacks.clear();
    out.hand_eye_imu_rotations.clear();
    out.hand_eye_lidar_rotations.clear();
    if (!RunOdometry(imu, sweeps, options.odometry, gyro, &out, &times, &failed_sweep)) {
      return on_sweeps_before_failure();
    }
    EstimateOffset(imu, options, &out);
    SolveRotation(imu, options, &out);
    if (!out.problems.empty()) return out;
  }
  AlignAndBuildKeyframes(imu, times, options, &out);
  return out;
}

CalibrationInitialization InitializeLidarImuFromOdometry(
    const sensors::ImuSamples& imu, const std::vector<lidar::LidarSweep>& sweeps,
    const std::vector<lidar::OdometryFrame>& odometry,
    const CalibrationInitializerOptions& options) {
  CheckImuStamps(imu);
  std::vector<SweepTimes> times;
  for (size_t k = 0; k < sweeps.size(); ++k) AppendSweepTimes(sweeps[k], k, &times);
  if (odometry.size() != sweeps.size()) {
    throw Error("InitializeLidarImuFromOdometry: " + std::to_string(odometry.size()) +
                " odometry frames for " + std::to_string(sweeps.size()) + " sweeps");
  }
  for (size_t k = 0; k < sweeps.size(); ++k) {
    if (odometry[k].t_ns != sweeps[k].t_ns) {
      throw Error("InitializeLidarImuFromOdometry: odometry frame " + std::to_string(k) +
                  " is not stamped like its sweep");
    }
  }
  CalibrationInitialization out;
  if (TooShort(imu, sweeps.size(), &out)) return out;
  out.odometry = odometry;
  FindRestPeriod(imu, options, &out);
  EstimateOffset(imu, options, &out);
  SolveRotation(imu, options, &out);
  if (!out.problems.empty()) return out;
  AlignAndBuildKeyframes(imu, times, options, &out);
  return out;
}

namespace {

// Step 5 on the keyframe slots: the inertial fit, and theta applied to out->q_I_L when the
// fit determines it. Theta enters to first order: a second fit starts from the corrected
// rotation. When the first fit does not determine theta (a straight drive at steady speed),
// q_I_L keeps its value and `fallbacks` says so.
void FitInertial(const sensors::ImuSamples& imu, const std::vector<KeyframeSlot>& slots,
                 const CalibrationInitializerOptions& options, CalibrationInitialization* out,
                 std::vector<Eigen::Vector3d>* p_O_I, std::vector<Eigen::Vector3d>* v_O_I) {
  const StillStart& rest = out->still_start;
  // The specific force at rest, R_W_I^T (0, 0, g), and the IMU's vertical.
  const Eigen::Vector3d f_rest =
      rest.q_W_I.conjugate() * Eigen::Vector3d(0.0, 0.0, rest.gravity_m_s2);
  const Eigen::Vector3d up_I = f_rest.normalized();
  double theta_total_rad = 0.0;
  bool applied = false;
  for (int iteration = 0; iteration < 2; ++iteration) {
    // The IMU orientation in O at the end of the rest period, through the first keyframe.
    const Eigen::Matrix3d R_I_L = out->q_I_L.toRotationMatrix();
    const Eigen::Matrix3d R_O_I_rest =
        slots.front().T_O_L.R() * R_I_L.transpose() *
        GyroRotation(imu, rest.gyro_bias_rad_s, slots.front().t_ns, rest.t_end_ns)
            .toRotationMatrix();
    InertialFit fit(imu, slots, options, R_I_L, rest.gyro_bias_rad_s, R_O_I_rest, f_rest, up_I,
                    out->still_start_is_low_excitation ? nullptr : &rest);
    fit.Solve(&out->inertial, p_O_I, v_O_I);
    if (!out->inertial.vertical_rotation_determined) break;
    applied = true;
    theta_total_rad += out->inertial.vertical_rotation_rad;
    out->q_I_L = (Eigen::Quaterniond(Eigen::AngleAxisd(out->inertial.vertical_rotation_rad, up_I)) *
                  out->q_I_L)
                     .normalized();
  }
  out->inertial.vertical_rotation_rad = theta_total_rad;
  out->inertial.vertical_rotation_determined = applied;
  if (applied) return;
  out->fallbacks.push_back(
      "the accelerations do not determine the LiDAR-IMU rotation about the vertical (sigma " +
      Format(out->inertial.vertical_rotation_std_rad * kRadToDeg) + " deg, limit " +
      Format(options.max_vertical_rotation_std_rad * kRadToDeg) +
      " deg): the rotation is not corrected about it");
}

void AlignAndBuildKeyframes(const sensors::ImuSamples& imu, const std::vector<SweepTimes>& sweeps,
                            const CalibrationInitializerOptions& options,
                            CalibrationInitialization* out_ptr) {
  CalibrationInitialization& out = *out_ptr;
  out.q_I_L = out.rotation.q_I_L;
  out.time_offset_lidar_imu_s = out.time_offset.offset_s;
  const std::vector<KeyframeSlot> slots = KeyframeSlots(imu, sweeps, options, &out);
  if (slots.size() < 2) {
    out.problems.push_back("fewer than two sweeps lie inside the IMU log");
    return;
  }
  std::vector<Eigen::Vector3d> p_O_I, v_O_I;
  FitInertial(imu, slots, options, &out, &p_O_I, &v_O_I);
  out.p_I_L = out.inertial.p_I_L;

  const geometry::Pose3d T_I_L(out.q_I_L, out.p_I_L);
  const geometry::Pose3d T_O_I_0 = slots.front().T_O_L * T_I_L.Inverse();
  out.T_W_O = GravityAlignedWorld(out.inertial.gravity_O_m_s2, T_O_I_0.R(), p_O_I.front());
  for (size_t k = 0; k < slots.size(); ++k) {
    const geometry::Pose3d T_W_I = out.T_W_O * slots[k].T_O_L * T_I_L.Inverse();
    Keyframe keyframe;
    keyframe.t_ns = slots[k].t_ns;
    keyframe.q_W_I = T_W_I.q.normalized();
    keyframe.p_W_I = out.T_W_O * p_O_I[k];
    keyframe.v_W_I = out.T_W_O.q * v_O_I[k];
    keyframe.b_g = out.still_start.gyro_bias_rad_s;
    out.keyframe_sweeps.push_back(slots[k].sweep);
    out.keyframes.push_back(keyframe);
  }
  out.ok = true;
}

}  // namespace

}  // namespace estimation
}  // namespace autocal
