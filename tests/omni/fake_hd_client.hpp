// SPDX-License-Identifier: Apache-2.0
#pragma once
// Steers the fake libHD (fake_hd/fake_hd.cpp) from a test. The test maps the same file the
// backend loads and resolves the fake's extra tf_fake_hd_* functions from it; the backend
// itself still loads the file through hd::load_library (dlopen + dlsym of the HD functions),
// exactly as it would load OpenHaptics. What passes here proves our binding against the HD
// API as the reference documents it, not against the real driver.
#include <dlfcn.h>

#include <stdexcept>
#include <string>

#include "fake_hd/fake_hd_control.h"

namespace toonforce::test {

// Paths of the fakes in the build tree (tests/omni/CMakeLists.txt).
inline constexpr const char* kFakeHd = TOONFORCE_FAKE_HD;
inline constexpr const char* kFakeHdMissingSymbol = TOONFORCE_FAKE_HD_MISSING_SYMBOL;
inline constexpr const char* kFakeHdV2 = TOONFORCE_FAKE_HD_V2;
inline constexpr const char* kFakeHdNeedsDep = TOONFORCE_FAKE_HD_NEEDS_DEP;

/// The statement every Omni test records, so a report says what it proves.
inline constexpr const char* kProves =
    "proves the OpenHaptics binding against the documented HD API behaviour, through a fake "
    "libHD of our own; not against the real driver";

class FakeHd {
 public:
  explicit FakeHd(const std::string& path = kFakeHd) {
    handle_ = dlopen(path.c_str(), RTLD_LAZY | RTLD_GLOBAL | RTLD_NODELETE);
    if (handle_ == nullptr) throw std::runtime_error(std::string("cannot load the fake libHD: ") + dlerror());
    bind("tf_fake_hd_reset", reset);
    bind("tf_fake_hd_set_manual", set_manual);
    bind("tf_fake_hd_step", step);
    bind("tf_fake_hd_set_version", set_version);
    bind("tf_fake_hd_set_limits", set_limits);
    bind("tf_fake_hd_set_calibration", set_calibration);
    bind("tf_fake_hd_set_calibration_update_error", set_calibration_update_error);
    bind("tf_fake_hd_set_inkwell", set_inkwell);
    bind("tf_fake_hd_set_model", set_model);
    bind("tf_fake_hd_set_buttons", set_buttons);
    bind("tf_fake_hd_inject_error", inject_error);
    bind("tf_fake_hd_inject_overrun", inject_overrun);
    bind("tf_fake_hd_set_callback_time", set_callback_time);
    bind("tf_fake_hd_pin_hand", pin_hand_raw_);
    bind("tf_fake_hd_spring_hand", spring_hand_raw_);
    bind("tf_fake_hd_set_motor_temperature", set_motor_temperature);
    bind("tf_fake_hd_set_temperature_supported", set_temperature_supported);
    bind("tf_fake_hd_get_stats", get_stats_);
    bind("tf_fake_hd_add_device", add_device);
    bind("tf_fake_hd_select_device", select_device);
  }

  TfFakeHdStats stats() const {
    TfFakeHdStats s{};
    get_stats_(&s);
    return s;
  }
  void pin_hand(double x_mm, double y_mm, double z_mm) const {
    const double p[3] = {x_mm, y_mm, z_mm};
    pin_hand_raw_(p);
  }
  void spring_hand(double x_mm, double y_mm, double z_mm, double k_n_per_m, double b_n_s_per_m) const {
    const double p[3] = {x_mm, y_mm, z_mm};
    spring_hand_raw_(p, k_n_per_m, b_n_s_per_m);
  }

  void (*reset)() = nullptr;
  void (*set_manual)(int) = nullptr;
  unsigned long (*step)(unsigned long) = nullptr;
  void (*set_version)(const char*) = nullptr;
  void (*set_limits)(double, double, double, double) = nullptr;
  void (*set_calibration)(unsigned int, int) = nullptr;
  void (*set_calibration_update_error)(unsigned int) = nullptr;
  void (*set_inkwell)(int) = nullptr;
  void (*set_model)(const char*) = nullptr;
  void (*set_buttons)(int) = nullptr;
  void (*inject_error)(unsigned int, int, int, unsigned long) = nullptr;
  void (*inject_overrun)(unsigned int) = nullptr;
  void (*set_callback_time)(double) = nullptr;
  void (*set_motor_temperature)(double) = nullptr;
  void (*set_temperature_supported)(int) = nullptr;
  int (*add_device)(const char* name, const char* serial) = nullptr;  // fake_hd_control.h
  int (*select_device)(const char* name) = nullptr;

 private:
  template <class F>
  void bind(const char* name, F& slot) {
    void* symbol = dlsym(handle_, name);
    if (symbol == nullptr) throw std::runtime_error(std::string("the fake libHD lacks ") + name);
    slot = reinterpret_cast<F>(symbol);
  }

  void* handle_ = nullptr;
  void (*pin_hand_raw_)(const double*) = nullptr;
  void (*spring_hand_raw_)(const double*, double, double) = nullptr;
  void (*get_stats_)(TfFakeHdStats*) = nullptr;
};

}  // namespace toonforce::test
