#pragma once

// Readers and writers for the CSV files of a dataset (datasets/README.md):
//   imu.csv                    t_ns,gx,gy,gz,ax,ay,az
//   wheel.csv                  t_ns,left_rad_s,right_rad_s
//   wheel_speed.csv            t_ns,left_m_s,right_m_s[,front_left_m_s,front_right_m_s]
//   odometry.csv               t_ns,speed_m_s,yaw_rate_rad_s
//   gnss.csv                   t_ns,lat_deg,lon_deg,alt_m,std_east_m,std_north_m,std_up_m
//   lidar.csv                  t_ns,file
//   groundtruth/trajectory.csv t_ns,px,py,pz,qx,qy,qz,qw,vx,vy,vz
// Readers check the header, the column count, every number (finite, no trailing
// characters), strictly increasing timestamps and the plausibility checks below; the first
// problem is a ParseError with file, line and column. Writers print every double as the
// shortest decimal that reads back exactly.

#include <string>
#include <vector>

#include "autocal/io/dataset.h"
#include "autocal/io/imu_plausibility.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace io {

// Wheel-rate plausibility: a car wheel (r ~ 0.3 m) at 300 km/h turns at ~280 rad/s.
// Larger rates mean rpm or deg/s.
constexpr double kMaxPlausibleWheelRateRadS = 500.0;

// Wheel-speed plausibility: 100 m/s is 360 km/h; larger values mean km/h or mph. A vehicle's
// yaw rate beyond 10 rad/s (a turn in 0.6 s) means deg/s.
constexpr double kMaxPlausibleWheelSpeedMS = 100.0;
constexpr double kMaxPlausibleYawRateRadS = 10.0;

// Stamps are nanoseconds. A median interval between rows shorter than 1 / rate for these
// rates is refused as another unit: stamped in microseconds, a 200 Hz IMU looks like 200 kHz,
// a 100 Hz wheel encoder like 100 kHz, a 10 Hz receiver or LiDAR like 10 kHz. Files with
// fewer than 11 rows are not checked.
constexpr double kMaxPlausibleImuRateHz = 10000.0;
constexpr double kMaxPlausibleWheelSampleRateHz = 10000.0;
constexpr double kMaxPlausibleGnssRateHz = 200.0;
constexpr double kMaxPlausibleSweepRateHz = 1000.0;

sensors::ImuSamples ReadImuCsv(const std::string& path, const ImuPlausibilityOptions& checks = {});
sensors::WheelSamples ReadWheelCsv(const std::string& path);
// The header decides the layout: three columns (rear pair) or five (rear pair, then front).
sensors::WheelSpeedSamples ReadWheelSpeedCsv(const std::string& path);
sensors::OdometrySamples ReadOdometryCsv(const std::string& path);
sensors::GnssFixes ReadGnssCsv(const std::string& path);
// When `sweep_directory` is not empty, each row's file must exist in it (the error names
// the row and the column of the file name).
std::vector<LidarSweepRef> ReadLidarCsv(const std::string& path,
                                        const std::string& sweep_directory = "");
// Quaternions are normalized; a norm off 1 by more than 1e-3 is an error.
Trajectory ReadTrajectoryCsv(const std::string& path);
// groundtruth/imu_bias.csv of a simulated log: t_ns, then b_g (rad/s) and b_a (m/s^2).
ImuBiasTrajectory ReadImuBiasCsv(const std::string& path);

// Writers throw autocal::Error on I/O failure or a non-finite value.
void WriteImuCsv(const std::string& path, const sensors::ImuSamples& samples);
void WriteWheelCsv(const std::string& path, const sensors::WheelSamples& samples);
// Five columns when the samples carry the front pair (all of them must, or none).
void WriteWheelSpeedCsv(const std::string& path, const sensors::WheelSpeedSamples& samples);
void WriteOdometryCsv(const std::string& path, const sensors::OdometrySamples& samples);
void WriteGnssCsv(const std::string& path, const sensors::GnssFixes& fixes);
void WriteLidarCsv(const std::string& path, const std::vector<LidarSweepRef>& sweeps);
void WriteTrajectoryCsv(const std::string& path, const Trajectory& trajectory);
void WriteImuBiasCsv(const std::string& path, const ImuBiasTrajectory& biases);

}  // namespace io
}  // namespace autocal
