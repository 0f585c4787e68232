#pragma once

// Initial wheel-IMU and GNSS-IMU time offsets of the offline calibration (docs/calibration.md,
// "Clock offsets of the wheels and GNSS"): before the solve, each offset the problem estimates
// starts at the cross-correlation of a signal both clocks see (estimation/clock_offsets.h),
// searched over +-1 s; the solve then refines it through the factors of Eq. K16.

#include <optional>
#include <string>
#include <vector>

#include "autocal/estimation/calibration_observability.h"
#include "autocal/estimation/clock_offsets.h"
#include "autocal/estimation/mount_initialization.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/sensors/calibration.h"

namespace autocal {
namespace pipeline {

struct ClockInitialization {
  std::optional<estimation::WheelImuOffset> wheel;       // when the problem estimates it
  std::optional<estimation::SeriesOffsetEstimate> gnss;  // likewise
  std::optional<estimation::UpAxisEstimate> up;  // gravity's up axis, when the mount was sought
  bool mount_from_data = false;  // the data's mount replaced a nominal one that was no guess
};

// The rear axle's speed (m/s) and yaw rate (rad/s) on the wheel clock from the dataset's wheel
// data in its form, through the nominal radii, speed scales or odometry scale and tracks of
// `calibration` (their scale does not matter to a correlation). Both empty without wheel data.
void WheelSpeedAndYawRate(const io::Dataset& dataset, const sensors::Calibration& calibration,
                          estimation::ScalarSeries* speed_m_s,
                          estimation::ScalarSeries* yaw_rate_rad_s);

// Sets calibration->time_offset_wheel_imu_s (wheel yaw rate against the gyro about q_I_V's up
// axis, or the speed's derivative against the forward accelerometer) and then
// time_offset_gnss_imu_s (the track's horizontal speed against the wheel speed on the IMU
// clock) for each offset the problem estimates and whose sensor the dataset has. An estimate
// that is not reliable keeps the value in *calibration (the nominal) and appends a warning
// naming why to *warnings; so does a GNSS offset without wheel data to compare with.
ClockInitialization InitializeClockOffsets(const io::Dataset& dataset, const io::Problem& problem,
                                           sensors::Calibration* calibration,
                                           std::vector<std::string>* warnings);

// The IMU mount q_I_V from the data (estimation/mount_initialization.h), when the problem
// estimates it and the dataset has wheel data: the up axis from gravity, the wheel clock
// (InitializeClockOffsets) with that up axis, then the forward axis from the wheel speed's
// changes and turns. A nominal mount further than max_nominal_deg from the data's (three prior
// sigmas) is no guess: the data's mount is then the solve's start and the centre of the
// mount's prior (*prior_centre), and a warning says so. Otherwise, or when the initialization
// fails (a warning names why), the nominal stays. Runs InitializeClockOffsets in either case.
ClockInitialization InitializeMountAndClocks(const io::Dataset& dataset, const io::Problem& problem,
                                             double max_nominal_deg,
                                             sensors::Calibration* calibration,
                                             sensors::Calibration* prior_centre,
                                             std::vector<std::string>* warnings);

// The IMU noise the factors use (docs/calibration.md, "IMU noise from the data"): sensors.yaml's
// densities, each replaced by the samples' scatter (sensors::MeasureImuScatter, Eq. N1) when
// that is at least kMinImuNoiseScale times the stated one, with a warning naming both (the
// vibration of a vehicle the datasheet does not know). The random walks stay as stated.
constexpr double kMinImuNoiseScale = 1.5;
sensors::ImuNoise ImuNoiseFromData(const io::Dataset& dataset, std::vector<std::string>* warnings);

// `dataset` as the calibration uses it: itself when ImuNoiseFromData keeps the stated noise,
// else a copy with the measured noise, held in *storage.
const io::Dataset& WithImuNoiseFromData(const io::Dataset& dataset,
                                        std::optional<io::Dataset>* storage,
                                        std::vector<std::string>* warnings);

// The wheel rows' noise from the data (docs/calibration.md, "Wheel noise from the data"): the
// wheels' yaw rate against the gyro about the mount's up axis, on one clock
// (estimation::CompareYawRates). When what that fit leaves exceeds the noise it should
// (sensors.yaml's yaw-rate noise with the gyro's averaged over the wheels' interval) by at
// least kMinWheelNoiseScale, the ratio is returned and a warning says so: every wheel row's
// sigma is scaled by it (a skid-steer robot slipping, odometry that follows something else).
// 1 otherwise, or when the comparison has too few samples.
constexpr double kMinWheelNoiseScale = 1.5;
double WheelNoiseScale(const io::Dataset& dataset, const sensors::Calibration& calibration,
                       const sensors::Calibration& nominal, std::vector<std::string>* warnings);

// Eq. C4: the mount's prior (the kVehicleRotation block of *blocks: centre and sigmas) fused
// with gravity's up axis of `init` (estimation::FuseUpAxis), when there is one and the
// problem gives calibration.ground_tilt_sigma_deg. The up axis's sigma is
// sqrt(ground_tilt^2 + (b / g)^2): the accelerometer's bias b tilts the mean specific force.
// b is the bias's mean over the span T averaged: its start (accel_bias_sigma) and its random
// walk (density q), whose mean over T has variance q^2 T / 3, so
// b^2 = accel_bias_sigma^2 + q^2 T / 3. The block's start and prior_centre->q_I_V move to the
// fused centre. The block's prior_source names the centre (the data's mount when
// init.mount_from_data), fused or not, for the warning of a direction held there.
void FuseUpAxisIntoMountPrior(const ClockInitialization& init, const io::Problem& problem,
                              double accel_bias_sigma_m_s2, double accel_random_walk_m_s3,
                              double gravity_m_s2, std::vector<estimation::EstimatedBlock>* blocks,
                              sensors::Calibration* prior_centre);

}  // namespace pipeline
}  // namespace autocal
