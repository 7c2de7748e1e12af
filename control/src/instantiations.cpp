// Explicit instantiations of the control stages for every scalar type, so each provably
// builds for double, float and Q16.16: the controller, and the servo loop with its safety
// layer on the run-time device seam.
#include "toonforce/control/controller.hpp"
#include "toonforce/control/servo_loop.hpp"
#include "toonforce/effects/instantiations.hpp"

#define TOONFORCE_DEFINE_CONTROL(S)                                                  \
  template class ::toonforce::VelocityEstimator<S>;                                  \
  template class ::toonforce::ForceSafety<S>;                                        \
  template class ::toonforce::Controller<::toonforce::RuntimeScene<S>>;              \
  template class ::toonforce::ThermalModel<S>;                                       \
  template class ::toonforce::Wide<S>;                                               \
  template class ::toonforce::ServoLoop<::toonforce::DriverRef, ::toonforce::RuntimeScene<S>>;
TOONFORCE_FOR_EACH_SCALAR(TOONFORCE_DEFINE_CONTROL)
