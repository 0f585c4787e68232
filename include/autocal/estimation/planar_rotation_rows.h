#pragma once

// The planar-rotation rows (Eq. F27) on the keyframes of a batch problem, with their sigma
// measured from the log (docs/keyframe_factors.md, "The vehicle turns about its own up axis",
// Eq. K15). A ground vehicle's roll and pitch rates are what the ground and the body add; on a
// rigid platform (a skid-steer robot) they are zero-mean and unrelated to the yaw rate, and the
// rows give the mount's roll and pitch from every turn. A car's body pitches when it brakes
// into a turn, a rate that follows the yaw rate: its problems leave the rows out.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <vector>

#include "autocal/estimation/keyframe.h"
#include "autocal/factors/loss.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace estimation {

// What the log's rates say about the rows (Eq. K15), from the keyframes' body rates in V at the
// initial mount, in time order.
struct PlanarRotationSpread {
  // Robust (1.4826 MAD) spread of the roll and pitch rates after their least-squares line on
  // the yaw rate is removed (that line is the initial mount's tilt, which the solve removes).
  Eigen::Vector2d sigma_rad_s = Eigen::Vector2d::Zero();
  // The line's slopes: the tilt of the initial mount the turns show, about V's y and -x axes.
  Eigen::Vector2d slope = Eigen::Vector2d::Zero();
  // sqrt(1 + 2 sum of the residuals' autocorrelation up to its first zero): a correlated spread
  // carries fewer independent rows; the rows' sigma is scaled by it.
  Eigen::Vector2d correlation_scale = Eigen::Vector2d::Ones();
  int samples = 0;

  // The rows' one sigma: the RMS over both axes of the spread times its correlation scale, at
  // least 1e-6 rad/s (noise-free rates would give an information that overflows). One for both
  // axes, so that the rows stay blind to the mount's yaw (Eq. F27b): the axes are the initial
  // mount's, and a sigma per axis would hold the yaw where it was measured.
  double RowSigmaRadS() const;
};

// Throws autocal::Error with fewer than 10 rates or a non-finite one.
PlanarRotationSpread MeasurePlanarRotationSpread(const std::vector<Eigen::Vector3d>& rates_V);

// The same for a whole log at the mount q_I_V: the gyro averaged over gyro_mean_span_s around
// every period_s from the first IMU sample to the last (the gyro bias cancels in the spread).
// Throws as above, or for a non-positive period.
PlanarRotationSpread MeasurePlanarRotationSpreadOfLog(const sensors::ImuSamples& imu,
                                                      const Eigen::Quaterniond& q_I_V,
                                                      double period_s, double gyro_mean_span_s);

struct PlanarRotationOptions {
  // 1-sigma of the roll and pitch rates in V, rad/s; 0: the spread measured from the log times
  // its correlation scale (Eq. K15).
  double sigma_rad_s = 0.0;
  double max_imu_gap_s = 0.0;     // bracketing IMU samples of a keyframe (as the wheel rows)
  double gyro_mean_span_s = 0.0;  // the rows take the mean gyro over this span (Eq. K13)
  factors::LossOptions loss = factors::FactorLossOptions().wheel;
};

struct PlanarRotationRows {
  int added = 0;
  double sigma_rad_s = 0.0;     // the rows' sigma
  PlanarRotationSpread spread;  // when measured
};

// Adds one PlanarRotationFactor per keyframe the IMU brackets, on its b_g and the
// calibration's q_I_V (which must already be in the problem with RightQuaternionManifold;
// whether it is estimated is the caller's). Ownership as AddWheelFactors. Throws
// autocal::Error as MeasurePlanarRotationSpread, for a negative sigma or gap.
PlanarRotationRows AddPlanarRotationFactors(ceres::Problem* problem, const sensors::ImuSamples& imu,
                                            std::vector<Keyframe>* keyframes,
                                            sensors::Calibration* calibration,
                                            const PlanarRotationOptions& options = {});

}  // namespace estimation
}  // namespace autocal
