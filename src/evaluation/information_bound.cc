#include "autocal/evaluation/information_bound.h"

#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/evaluation/trajectory_errors.h"
#include "estimation/keyframe_interpolation.h"

namespace autocal {
namespace evaluation {

namespace {

// The true biases at t_ns, linear between the samples around it; false outside them.
bool BiasAt(const io::ImuBiasTrajectory& biases, int64_t t_ns, Eigen::Vector3d* b_g,
            Eigen::Vector3d* b_a) {
  const std::optional<estimation::internal::Bracket> at =
      estimation::internal::FindBracket(biases, t_ns, std::numeric_limits<int64_t>::max());
  if (!at) return false;
  const io::ImuBiasSample& before = biases[at->first];
  const io::ImuBiasSample& after = biases[at->second];
  *b_g = before.b_g + at->s * (after.b_g - before.b_g);
  *b_a = before.b_a + at->s * (after.b_a - before.b_a);
  return true;
}

}  // namespace

estimation::StateSetter TruthSetter(const io::Dataset& dataset) {
  if (dataset.groundtruth_trajectory.empty() || !dataset.groundtruth_calibration) return {};
  auto truth = std::make_shared<const io::Trajectory>(dataset.groundtruth_trajectory);
  auto biases = std::make_shared<const io::ImuBiasTrajectory>(dataset.groundtruth_imu_bias);
  const sensors::Calibration calibration = *dataset.groundtruth_calibration;
  // Truth samples farther apart than the evaluation's interpolation gap leave the keyframes
  // between them as they are.
  const int64_t max_gap_ns = SecondsToNs(TrajectoryErrorOptions().max_interpolation_gap_s);
  return [truth, biases, calibration, max_gap_ns](std::vector<estimation::Keyframe>* keyframes,
                                                  sensors::Calibration* c) {
    // Matched pairs: the keyframes' poses and the truth at their stamps.
    std::vector<size_t> matched;
    io::Trajectory estimate, at_keyframes;
    for (size_t k = 0; k < keyframes->size(); ++k) {
      const estimation::Keyframe& kf = (*keyframes)[k];
      io::TrajectorySample sample;
      bool exact = false;
      if (!TruthAt(*truth, kf.t_ns, max_gap_ns, &sample, &exact)) continue;
      io::TrajectorySample e;
      e.t_ns = kf.t_ns;
      e.T_W_I.q = kf.q_W_I;
      e.T_W_I.p = kf.p_W_I;
      estimate.push_back(e);
      at_keyframes.push_back(sample);
      matched.push_back(k);
    }
    if (matched.size() < 2) {
      throw Error("information bound: fewer than two keyframes lie within the ground truth");
    }
    // p_true = Rz p_est + t, so p_est = Rz^T (p_true - t).
    const Alignment4Dof a = AlignYawAndTranslation(estimate, at_keyframes);
    const Eigen::Quaterniond Rz_inverse(Eigen::AngleAxisd(-a.yaw_rad, Eigen::Vector3d::UnitZ()));
    for (size_t i = 0; i < matched.size(); ++i) {
      estimation::Keyframe& kf = (*keyframes)[matched[i]];
      const io::TrajectorySample& t = at_keyframes[i];
      kf.q_W_I = (Rz_inverse * t.T_W_I.q).normalized();
      kf.p_W_I = Rz_inverse * (t.T_W_I.p - a.translation_m);
      kf.v_W_I = Rz_inverse * t.v_W_I;
      // Body-frame quantities: the world's yaw does not touch them.
      BiasAt(*biases, kf.t_ns, &kf.b_g, &kf.b_a);
    }
    *c = calibration;
  };
}

}  // namespace evaluation
}  // namespace autocal
