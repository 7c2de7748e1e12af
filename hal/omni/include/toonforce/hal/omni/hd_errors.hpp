// SPDX-License-Identifier: Apache-2.0
#pragma once
/// HD error codes (OMNI.md §2.3) mapped onto our fault model (docs/OMNI.md, HD errors):
///  - force errors (HD_WARM_MOTORS, HD_EXCEEDED_MAX_FORCE, ..._IMPULSE, ..._VELOCITY,
///    HD_FORCE_ERROR) degrade: zero force for a hold time, then ramp back;
///  - communication, timer and scheduler errors stop the loop (HDU's hduIsSchedulerError set),
///    and so do device faults and the licence error;
///  - frame and function errors inside the loop mean this binding used the API wrongly: stop.
/// Every message names the HD error. Names and meanings are ours (paraphrased from the
/// reference); nothing here allocates, so the servo thread may use it.

#include <cstdint>
#include <string_view>

#include "toonforce/hal/device.hpp"
#include "toonforce/hal/omni/hd_api.hpp"

namespace toonforce::hd {

enum class ErrorClass : std::uint8_t {
  kNone,           ///< HD_SUCCESS
  kFunction,       ///< 0x100-0x104: a call with a bad enum, value, type or handle
  kForce,          ///< 0x200-0x204: degrade and ramp back
  kDevice,         ///< HD_DEVICE_FAULT, HD_DEVICE_ALREADY_INITIATED
  kCommunication,  ///< HD_COMM_ERROR, HD_COMM_CONFIG_ERROR
  kScheduler,      ///< HD_TIMER_ERROR, HD_INVALID_PRIORITY, HD_SCHEDULER_FULL
  kFrame,          ///< HD_ILLEGAL_BEGIN, HD_ILLEGAL_END, HD_FRAME_ERROR
  kLicense,        ///< HD_INVALID_LICENSE
  kUnknown,        ///< a code the reference does not list: treated as fatal
};

constexpr ErrorClass classify(HDerror code) noexcept {
  switch (code) {
    case kSuccess: return ErrorClass::kNone;
    case kInvalidEnum:
    case kInvalidValue:
    case kInvalidOperation:
    case kInvalidInputType:
    case kBadHandle: return ErrorClass::kFunction;
    case kWarmMotors:
    case kExceededMaxForce:
    case kExceededMaxForceImpulse:
    case kExceededMaxVelocity:
    case kForceError: return ErrorClass::kForce;
    case kDeviceFault:
    case kDeviceAlreadyInitiated: return ErrorClass::kDevice;
    case kCommError:
    case kCommConfigError: return ErrorClass::kCommunication;
    case kTimerError:
    case kInvalidPriority:
    case kSchedulerFull: return ErrorClass::kScheduler;
    case kIllegalBegin:
    case kIllegalEnd:
    case kFrameError: return ErrorClass::kFrame;
    case kInvalidLicense: return ErrorClass::kLicense;
    default: return ErrorClass::kUnknown;
  }
}

/// Whether an error inside the servo loop stops it (everything but a force error).
constexpr bool is_fatal(ErrorClass c) noexcept { return c != ErrorClass::kNone && c != ErrorClass::kForce; }

/// The device status a fatal error class gives (kOk for none and for force errors).
constexpr DeviceStatus device_status(ErrorClass c) noexcept {
  switch (c) {
    case ErrorClass::kNone:
    case ErrorClass::kForce: return DeviceStatus::kOk;
    case ErrorClass::kCommunication: return DeviceStatus::kDisconnected;
    case ErrorClass::kFunction:
    case ErrorClass::kFrame: return DeviceStatus::kProtocolError;
    case ErrorClass::kDevice:
    case ErrorClass::kScheduler:
    case ErrorClass::kLicense:
    case ErrorClass::kUnknown: return DeviceStatus::kDeviceFault;
  }
  return DeviceStatus::kDeviceFault;
}

/// "HD_COMM_ERROR"; "HD error" for a code the reference does not list.
std::string_view error_name(HDerror code) noexcept;
/// One sentence on what the error means and what happens (our words).
std::string_view error_meaning(HDerror code) noexcept;
std::string_view to_string(ErrorClass c) noexcept;

}  // namespace toonforce::hd
