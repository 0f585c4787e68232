#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace sensors {

const char* WheelFormName(WheelForm form) {
  switch (form) {
    case WheelForm::kAngularRates:
      return "angular_rates";
    case WheelForm::kLinearSpeeds:
      return "linear_speeds";
    case WheelForm::kSpeedYawRate:
      break;
  }
  return "speed_yaw_rate";
}

bool ParseWheelForm(const std::string& name, WheelForm* form) {
  for (WheelForm f :
       {WheelForm::kAngularRates, WheelForm::kLinearSpeeds, WheelForm::kSpeedYawRate}) {
    if (name == WheelFormName(f)) {
      *form = f;
      return true;
    }
  }
  return false;
}

const char* WheelFormFile(WheelForm form) {
  switch (form) {
    case WheelForm::kAngularRates:
      return "wheel.csv";
    case WheelForm::kLinearSpeeds:
      return "wheel_speed.csv";
    case WheelForm::kSpeedYawRate:
      break;
  }
  return "odometry.csv";
}

}  // namespace sensors
}  // namespace autocal
