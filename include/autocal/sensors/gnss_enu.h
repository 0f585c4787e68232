#pragma once

// Geodetic (WGS84 latitude, longitude, ellipsoidal height) to the local ENU world frame W,
// through GeographicLib's LocalCartesian (docs/factors.md, "GNSS factor"). The origin is the
// first fix of a log unless given otherwise.

#include <Eigen/Core>
#include <memory>

#include "autocal/sensors/measurements.h"

namespace GeographicLib {
class LocalCartesian;
}  // namespace GeographicLib

namespace autocal {
namespace sensors {

class EnuConverter {
 public:
  // Throws autocal::Error for a non-finite origin or one outside [-90, 90] x [-180, 180].
  EnuConverter(double lat0_deg, double lon0_deg, double alt0_m);
  // The origin at the first fix; throws autocal::Error when there is none.
  static EnuConverter AtFirstFix(const GnssFixes& fixes);

  EnuConverter(const EnuConverter& other);
  EnuConverter& operator=(const EnuConverter& other);
  ~EnuConverter();

  // ENU position of a geodetic point (metres); throws autocal::Error on invalid input.
  Eigen::Vector3d ToEnu(double lat_deg, double lon_deg, double alt_m) const;
  Eigen::Vector3d ToEnu(const GnssFix& fix) const {
    return ToEnu(fix.lat_deg, fix.lon_deg, fix.alt_m);
  }
  // Inverse of ToEnu: returns (lat_deg, lon_deg, alt_m).
  Eigen::Vector3d ToGeodetic(const Eigen::Vector3d& p_enu_m) const;

  double lat0_deg() const { return lat0_deg_; }
  double lon0_deg() const { return lon0_deg_; }
  double alt0_m() const { return alt0_m_; }

 private:
  double lat0_deg_;
  double lon0_deg_;
  double alt0_m_;
  std::unique_ptr<GeographicLib::LocalCartesian> local_;
};

}  // namespace sensors
}  // namespace autocal
