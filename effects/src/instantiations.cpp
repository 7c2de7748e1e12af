// SPDX-License-Identifier: Apache-2.0
// Explicit instantiations of every law for every scalar type (see instantiations.hpp).
#include "toonforce/effects/instantiations.hpp"

#define TOONFORCE_DEFINE_EFFECTS(S) TOONFORCE_EFFECT_TEMPLATES(, S)
TOONFORCE_FOR_EACH_SCALAR(TOONFORCE_DEFINE_EFFECTS)
