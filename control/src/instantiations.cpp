// Explicit instantiations of the control stages for every scalar type, so each provably
// builds for double, float and Q16.16.
#include "toonforce/control/controller.hpp"
#include "toonforce/effects/instantiations.hpp"

#define TOONFORCE_DEFINE_CONTROL(S)                                        \
  template class ::toonforce::VelocityEstimator<S>;                        \
  template class ::toonforce::ForceSafety<S>;                              \
  template class ::toonforce::Controller<::toonforce::RuntimeScene<S>>;
TOONFORCE_FOR_EACH_SCALAR(TOONFORCE_DEFINE_CONTROL)
