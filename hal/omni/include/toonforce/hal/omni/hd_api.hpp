// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Our own declarations of the part of the OpenHaptics HD C API this backend calls, written
/// from the documented ABI (docs/OMNI.md §2.1-2.3: plain cdecl, HHD/HDenum/HDerror
/// are unsigned int, HDboolean unsigned char, HDErrorInfo returned by value; constant values as
/// the HD reference documents them). No vendor header is included or needed: the library is
/// loaded at run time (hd_library.hpp), and none of its files are shipped (licence, §2.3).

#include <cstdint>

// The same refusal as cmake/ToonforceOmniArchitecture.cmake, for a build that bypasses it: on
// 32-bit x86 the vendor declares the API __stdcall, and these cdecl declarations would corrupt
// the stack on every call.
// (clang-format would split the message line with a backslash.)
// clang-format off
#if defined(__i386__)
#error "toonforce's Omni backend cannot be built for 32-bit x86: OpenHaptics' HD API is __stdcall there; build for x86-64"
#endif
// clang-format on

namespace toonforce::hd {

// ---- Types (OMNI.md §2.1) ------------------------------------------------------------------
using HHD = unsigned int;
using HDenum = unsigned int;
using HDerror = unsigned int;
using HDuint = unsigned int;
using HDint = int;
using HDboolean = unsigned char;
using HDdouble = double;
using HDlong = long;
using HDulong = unsigned long;
using HDushort = unsigned short;
using HDstring = const char*;
using HDSchedulerHandle = unsigned long;
using HDCallbackCode = unsigned int;
using HDWaitCode = unsigned int;

/// Returned by value by hdGetError(): the most recent error first, kSuccess when none is left.
struct HDErrorInfo {
  HDerror errorCode;      // NOLINT(readability-identifier-naming): the documented layout
  int internalErrorCode;  // NOLINT(readability-identifier-naming)
  HHD hHD;                // NOLINT(readability-identifier-naming)
};

extern "C" {
/// A scheduler callback; returns kCallbackDone or kCallbackContinue.
using HDSchedulerCallback = HDCallbackCode (*)(void* user_data);
}

inline constexpr HDCallbackCode kCallbackDone = 0;
inline constexpr HDCallbackCode kCallbackContinue = 1;
inline constexpr HHD kInvalidHandle = 0xFFFFFFFFU;
inline constexpr HDboolean kTrue = 1;
inline constexpr HDboolean kFalse = 0;
inline constexpr HDushort kMaxSchedulerPriority = 0xFFFF;
inline constexpr HDushort kDefaultSchedulerPriority = 0x7FFF;

// ---- Error codes (OMNI.md §2.3) -------------------------------------------------------------
inline constexpr HDerror kSuccess = 0x0000;
// function errors
inline constexpr HDerror kInvalidEnum = 0x0100;
inline constexpr HDerror kInvalidValue = 0x0101;
inline constexpr HDerror kInvalidOperation = 0x0102;
inline constexpr HDerror kInvalidInputType = 0x0103;
inline constexpr HDerror kBadHandle = 0x0104;
// force errors
inline constexpr HDerror kWarmMotors = 0x0200;
inline constexpr HDerror kExceededMaxForce = 0x0201;
inline constexpr HDerror kExceededMaxForceImpulse = 0x0202;
inline constexpr HDerror kExceededMaxVelocity = 0x0203;
inline constexpr HDerror kForceError = 0x0204;
// device errors
inline constexpr HDerror kDeviceFault = 0x0300;
inline constexpr HDerror kDeviceAlreadyInitiated = 0x0301;
inline constexpr HDerror kCommError = 0x0302;
inline constexpr HDerror kCommConfigError = 0x0303;
inline constexpr HDerror kTimerError = 0x0304;
// frame errors
inline constexpr HDerror kIllegalBegin = 0x0400;
inline constexpr HDerror kIllegalEnd = 0x0401;
inline constexpr HDerror kFrameError = 0x0402;
// scheduler errors
inline constexpr HDerror kInvalidPriority = 0x0500;
inline constexpr HDerror kSchedulerFull = 0x0501;
// licence
inline constexpr HDerror kInvalidLicense = 0x0600;

// ---- Get parameters -------------------------------------------------------------------------
inline constexpr HDenum kCurrentButtons = 0x2000;
inline constexpr HDenum kCurrentInkwellSwitch = 0x2002;
inline constexpr HDenum kCurrentPosition = 0x2050;            ///< [mm], 3 doubles
inline constexpr HDenum kCurrentVelocity = 0x2051;            ///< [mm/s], 3 doubles, smoothed by the library
inline constexpr HDenum kCurrentJointAngles = 0x2100;         ///< [rad], 3 doubles
inline constexpr HDenum kCurrentGimbalAngles = 0x2150;        ///< [rad], 3 doubles
inline constexpr HDenum kVersion = 0x2500;                    ///< string
inline constexpr HDenum kDeviceModelType = 0x2501;            ///< string
inline constexpr HDenum kDeviceDriverVersion = 0x2502;        ///< string
inline constexpr HDenum kDeviceVendor = 0x2503;               ///< string
inline constexpr HDenum kDeviceSerialNumber = 0x2504;         ///< string
inline constexpr HDenum kMaxWorkspaceDimensions = 0x2550;     ///< [mm] minx miny minz maxx maxy maxz
inline constexpr HDenum kUsableWorkspaceDimensions = 0x2551;  ///< [mm] same layout
inline constexpr HDenum kTabletopOffset = 0x2552;             ///< [mm], 1 double
inline constexpr HDenum kInputDof = 0x2553;                   ///< int
inline constexpr HDenum kOutputDof = 0x2554;                  ///< int
inline constexpr HDenum kCalibrationStyle = 0x2555;           ///< int bitmask
inline constexpr HDenum kUpdateRate = 0x2600;                 ///< [Hz], 1 double
inline constexpr HDenum kInstantaneousUpdateRate = 0x2601;    ///< [Hz], 1 double
inline constexpr HDenum kNominalMaxStiffness = 0x2602;        ///< [N/mm]
inline constexpr HDenum kNominalMaxForce = 0x2603;            ///< [N], peak at room temperature
inline constexpr HDenum kNominalMaxContinuousForce = 0x2604;  ///< [N]
inline constexpr HDenum kMotorTemperature = 0x2605;           ///< 3 or 6 doubles, 0 cold .. 1 warm
inline constexpr HDenum kSoftwareVelocityLimit = 0x2606;      ///< [mm/s]
inline constexpr HDenum kSoftwareForceImpulseLimit = 0x2607;  ///< [N/ms]
inline constexpr HDenum kForceRampingRate = 0x2608;           ///< [N/s]
inline constexpr HDenum kNominalMaxDamping = 0x2609;          ///< [N s/mm]
// ---- Set parameters -------------------------------------------------------------------------
inline constexpr HDenum kCurrentForce = 0x2700;  ///< [N], 3 doubles, device frame
// ---- Capabilities (hdEnable / hdDisable) ----------------------------------------------------
inline constexpr HDenum kForceOutput = 0x4000;
inline constexpr HDenum kMaxForceClamping = 0x4001;
inline constexpr HDenum kForceRamping = 0x4002;
inline constexpr HDenum kSoftwareForceLimit = 0x4003;
inline constexpr HDenum kOneFrameLimit = 0x4004;
// ---- Calibration ----------------------------------------------------------------------------
inline constexpr HDenum kCalibrationOk = 0x5000;
inline constexpr HDenum kCalibrationNeedsUpdate = 0x5001;
inline constexpr HDenum kCalibrationNeedsManualInput = 0x5002;
inline constexpr int kCalibrationEncoderReset = 1 << 0;
inline constexpr int kCalibrationAuto = 1 << 1;
inline constexpr int kCalibrationInkwell = 1 << 2;

/// The functions we resolve with dlsym, one pointer each; every one is required. Members are
/// named exactly as the C symbols, so a call reads as in the reference guide.
// NOLINTBEGIN(readability-identifier-naming)
struct HdFunctions {
  HHD (*hdInitDevice)(HDstring config_name) = nullptr;
  void (*hdDisableDevice)(HHD device) = nullptr;
  void (*hdMakeCurrentDevice)(HHD device) = nullptr;
  void (*hdBeginFrame)(HHD device) = nullptr;
  void (*hdEndFrame)(HHD device) = nullptr;
  HDErrorInfo (*hdGetError)() = nullptr;
  HDstring (*hdGetErrorString)(HDerror code) = nullptr;
  void (*hdEnable)(HDenum cap) = nullptr;
  void (*hdDisable)(HDenum cap) = nullptr;
  HDboolean (*hdIsEnabled)(HDenum cap) = nullptr;
  void (*hdGetBooleanv)(HDenum name, HDboolean* values) = nullptr;
  void (*hdGetIntegerv)(HDenum name, HDint* values) = nullptr;
  void (*hdGetDoublev)(HDenum name, HDdouble* values) = nullptr;
  HDstring (*hdGetString)(HDenum name) = nullptr;
  void (*hdSetDoublev)(HDenum name, const HDdouble* values) = nullptr;
  HDenum (*hdCheckCalibration)() = nullptr;
  void (*hdUpdateCalibration)(HDenum style) = nullptr;
  void (*hdStartScheduler)() = nullptr;
  void (*hdStopScheduler)() = nullptr;
  void (*hdSetSchedulerRate)(HDulong rate_hz) = nullptr;
  HDSchedulerHandle (*hdScheduleAsynchronous)(HDSchedulerCallback callback, void* user_data,
                                              HDushort priority) = nullptr;
  void (*hdUnschedule)(HDSchedulerHandle handle) = nullptr;
  HDdouble (*hdGetSchedulerTimeStamp)() = nullptr;
};
// NOLINTEND(readability-identifier-naming)

}  // namespace toonforce::hd
