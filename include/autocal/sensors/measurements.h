#pragma once

// Raw measurement types, exactly as a dataset carries them (DESIGN.md "Data formats").
// Stamps are int64 nanoseconds on the sensor's own clock.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace autocal {
namespace sensors {

// One IMU sample in the IMU frame I: body rate and specific force (gravity included).
struct ImuSample {
  int64_t t_ns = 0;
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_m_s2 = Eigen::Vector3d::Zero();
};

// Angular rates of the left and right rear wheels (positive when driving forward).
struct WheelSample {
  int64_t t_ns = 0;
  double left_rad_s = 0.0;
  double right_rad_s = 0.0;
};

// Linear speeds of the rear wheels in m/s (CAN wheel speeds), positive when driving forward;
// a four-wheel log also carries the front pair (has_front), which the rear-axle model of the
// vehicle frame V does not use (the front wheels steer).
struct WheelSpeedSample {
  int64_t t_ns = 0;
  double left_m_s = 0.0;   // rear left
  double right_m_s = 0.0;  // rear right
  bool has_front = false;
  double front_left_m_s = 0.0;
  double front_right_m_s = 0.0;
};

// The body twist a vehicle controller publishes (nav_msgs/Odometry, geometry_msgs/Twist):
// forward speed and yaw rate, already computed from the wheels with the controller's own
// radius and wheel separation.
struct OdometrySample {
  int64_t t_ns = 0;
  double speed_m_s = 0.0;       // twist linear.x, negative when reversing
  double yaw_rate_rad_s = 0.0;  // twist angular.z, positive counter-clockwise
};

// A GNSS position fix of the antenna A with the receiver's 1-sigma (east, north, up).
// Heights are ellipsoidal (WGS84).
struct GnssFix {
  int64_t t_ns = 0;
  double lat_deg = 0.0;
  double lon_deg = 0.0;
  double alt_m = 0.0;
  Eigen::Vector3d std_enu_m = Eigen::Vector3d::Ones();
};

using ImuSamples = std::vector<ImuSample>;
using WheelSamples = std::vector<WheelSample>;
using GnssFixes = std::vector<GnssFix>;
using WheelSpeedSamples = std::vector<WheelSpeedSample>;
using OdometrySamples = std::vector<OdometrySample>;

}  // namespace sensors
}  // namespace autocal
