#include "autocal/sensors/gnss_enu.h"

#include <GeographicLib/LocalCartesian.hpp>
#include <cmath>
#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace sensors {

namespace {

void CheckGeodetic(double lat_deg, double lon_deg, double alt_m, const char* what) {
  if (!std::isfinite(lat_deg) || !std::isfinite(lon_deg) || !std::isfinite(alt_m) ||
      std::abs(lat_deg) > 90.0 || std::abs(lon_deg) > 180.0) {
    throw Error(std::string(what) + ": invalid geodetic position (lat " + std::to_string(lat_deg) +
                " deg, lon " + std::to_string(lon_deg) + " deg, alt " + std::to_string(alt_m) +
                " m); expected finite values with |lat| <= 90 and |lon| <= 180");
  }
}

}  // namespace

EnuConverter::EnuConverter(double lat0_deg, double lon0_deg, double alt0_m)
    : lat0_deg_(lat0_deg), lon0_deg_(lon0_deg), alt0_m_(alt0_m) {
  CheckGeodetic(lat0_deg, lon0_deg, alt0_m, "ENU origin");
  local_ = std::make_unique<GeographicLib::LocalCartesian>(lat0_deg, lon0_deg, alt0_m);
}

EnuConverter EnuConverter::AtFirstFix(const GnssFixes& fixes) {
  if (fixes.empty()) throw Error("ENU origin: no GNSS fix to place it at");
  return EnuConverter(fixes.front().lat_deg, fixes.front().lon_deg, fixes.front().alt_m);
}

EnuConverter::EnuConverter(const EnuConverter& other)
    : EnuConverter(other.lat0_deg_, other.lon0_deg_, other.alt0_m_) {}

EnuConverter& EnuConverter::operator=(const EnuConverter& other) {
  if (this != &other) {
    lat0_deg_ = other.lat0_deg_;
    lon0_deg_ = other.lon0_deg_;
    alt0_m_ = other.alt0_m_;
    local_ = std::make_unique<GeographicLib::LocalCartesian>(*other.local_);
  }
  return *this;
}

EnuConverter::~EnuConverter() = default;

Eigen::Vector3d EnuConverter::ToEnu(double lat_deg, double lon_deg, double alt_m) const {
  CheckGeodetic(lat_deg, lon_deg, alt_m, "GNSS fix");
  Eigen::Vector3d p;
  local_->Forward(lat_deg, lon_deg, alt_m, p.x(), p.y(), p.z());
  return p;
}

Eigen::Vector3d EnuConverter::ToGeodetic(const Eigen::Vector3d& p_enu_m) const {
  if (!p_enu_m.allFinite()) throw Error("ENU position is not finite");
  Eigen::Vector3d lla;
  local_->Reverse(p_enu_m.x(), p_enu_m.y(), p_enu_m.z(), lla.x(), lla.y(), lla.z());
  return lla;
}

}  // namespace sensors
}  // namespace autocal
