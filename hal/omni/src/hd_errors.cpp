// SPDX-License-Identifier: Apache-2.0
// Names and meanings of the HD error codes (OMNI.md §2.3), in our own words.
#include "toonforce/hal/omni/hd_errors.hpp"

namespace toonforce::hd {

std::string_view error_name(HDerror code) noexcept {
  switch (code) {
    case kSuccess: return "HD_SUCCESS";
    case kInvalidEnum: return "HD_INVALID_ENUM";
    case kInvalidValue: return "HD_INVALID_VALUE";
    case kInvalidOperation: return "HD_INVALID_OPERATION";
    case kInvalidInputType: return "HD_INVALID_INPUT_TYPE";
    case kBadHandle: return "HD_BAD_HANDLE";
    case kWarmMotors: return "HD_WARM_MOTORS";
    case kExceededMaxForce: return "HD_EXCEEDED_MAX_FORCE";
    case kExceededMaxForceImpulse: return "HD_EXCEEDED_MAX_FORCE_IMPULSE";
    case kExceededMaxVelocity: return "HD_EXCEEDED_MAX_VELOCITY";
    case kForceError: return "HD_FORCE_ERROR";
    case kDeviceFault: return "HD_DEVICE_FAULT";
    case kDeviceAlreadyInitiated: return "HD_DEVICE_ALREADY_INITIATED";
    case kCommError: return "HD_COMM_ERROR";
    case kCommConfigError: return "HD_COMM_CONFIG_ERROR";
    case kTimerError: return "HD_TIMER_ERROR";
    case kIllegalBegin: return "HD_ILLEGAL_BEGIN";
    case kIllegalEnd: return "HD_ILLEGAL_END";
    case kFrameError: return "HD_FRAME_ERROR";
    case kInvalidPriority: return "HD_INVALID_PRIORITY";
    case kSchedulerFull: return "HD_SCHEDULER_FULL";
    case kInvalidLicense: return "HD_INVALID_LICENSE";
    default: return "HD error";
  }
}

std::string_view error_meaning(HDerror code) noexcept {
  switch (code) {
    case kSuccess: return "no error";
    case kInvalidEnum:
    case kInvalidValue:
    case kInvalidOperation:
    case kInvalidInputType:
    case kBadHandle:
      return "the library rejected a call (a parameter this device does not support, or a call "
             "at the wrong time); inside the servo loop that is a fault of this binding, so the "
             "loop stopped";
    case kWarmMotors:
      return "the library's motor thermal model says the motors are warm; force is held at zero "
             "until they cool, then ramped back";
    case kExceededMaxForce:
      return "a commanded force exceeded what the device can render; force was zeroed and is "
             "ramped back";
    case kExceededMaxForceImpulse:
      return "the commanded force changed too fast (a kick); force was zeroed and is ramped back";
    case kExceededMaxVelocity:
      return "the handle moved faster than the library's safety limit; force was zeroed and is "
             "ramped back";
    case kForceError: return "incompatible force commands in one frame; force was zeroed and is ramped back";
    case kDeviceFault: return "the device or its driver reported a fault; the servo loop stopped";
    case kDeviceAlreadyInitiated:
      return "the device is already initialised (by this or another program); the servo loop "
             "stopped";
    case kCommError:
      return "communication with the device failed (cable, USB or Ethernet link); the servo loop "
             "stopped";
    case kCommConfigError:
      return "the driver's communication set-up is wrong (device configuration); the servo loop "
             "stopped";
    case kTimerError: return "the servo timer could not start or keep its rate; the servo loop stopped";
    case kIllegalBegin:
    case kIllegalEnd:
    case kFrameError:
      return "a begin/end frame was used out of order (a fault of this binding); the servo loop "
             "stopped";
    case kInvalidPriority:
    case kSchedulerFull: return "the vendor scheduler refused a callback; the servo loop stopped";
    case kInvalidLicense: return "the OpenHaptics licence check failed; the servo loop stopped";
    default: return "an error code the OpenHaptics reference does not list; the servo loop stopped";
  }
}

std::string_view to_string(ErrorClass c) noexcept {
  switch (c) {
    case ErrorClass::kNone: return "none";
    case ErrorClass::kFunction: return "function error";
    case ErrorClass::kForce: return "force error";
    case ErrorClass::kDevice: return "device error";
    case ErrorClass::kCommunication: return "communication error";
    case ErrorClass::kScheduler: return "scheduler error";
    case ErrorClass::kFrame: return "frame error";
    case ErrorClass::kLicense: return "licence error";
    case ErrorClass::kUnknown: return "unknown error";
  }
  return "?";
}

}  // namespace toonforce::hd
