// SPDX-License-Identifier: Apache-2.0
// Explicit instantiations of the control stages for every scalar type, so each provably
// builds for double, float and Q16.16: the servo loop with every stage on the run-time device
// seam and the library's run-time scene, and replay's loop (effects.md §6 stages only).
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/effects/instantiations.hpp"

// S is a template argument: parentheses would not compile.
// NOLINTBEGIN(bugprone-macro-parentheses)
#define TOONFORCE_DEFINE_CONTROL(S)                                                                                  \
  template class ::toonforce::VelocityEstimator<S>;                                                                  \
  template class ::toonforce::ForceSafety<S>;                                                                        \
  template class ::toonforce::ThermalModel<S>;                                                                       \
  template class ::toonforce::Wide<S>;                                                                               \
  template class ::toonforce::Engage<S>;                                                                             \
  template class ::toonforce::MotionLimits<S>;                                                                       \
  template class ::toonforce::ServoLoop<::toonforce::DriverRef, ::toonforce::RuntimeScene<S>>;                       \
  template class ::toonforce::ServoLoop<::toonforce::DriverRef, ::toonforce::RuntimeScene<S>, ::toonforce::NullPins, \
                                        ::toonforce::kSpecStages>;
// NOLINTEND(bugprone-macro-parentheses)
TOONFORCE_FOR_EACH_SCALAR(TOONFORCE_DEFINE_CONTROL)
