# SPDX-License-Identifier: Apache-2.0
# An instruction budget per tick on the target (as tests/budget_test.cpp's callgrind one on the
# host): every tick of every motion of SCENE, as counted exactly by its image under QEMU
# (firmware/main.cpp's "count" lines in OUTPUT), costs at most BUDGET instructions for WHAT:
# "loop" (replay's whole loop tick, read to write: effects.md §6 stages, stamped time), "every"
# (the whole loop tick with every stage at 1 kHz) or "effects" (the scene's effects plus the
# safety stage); and, with MEAN_BUDGET, their mean over each bundled motion at most that (not
# over the searched inputs' strikes, search_*: built to be expensive on every tick, they are
# held to the per-tick budget and the static bound, not to a mean of normal use). Variables:
# OUTPUT SCENE WHAT BUDGET [MEAN_BUDGET].
foreach(var OUTPUT SCENE WHAT BUDGET)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "check_budget.cmake: ${var} is not set")
  endif()
endforeach()
if(NOT EXISTS "${OUTPUT}")
  message(FATAL_ERROR "${OUTPUT}: no output of the image (its run test failed or did not run)")
endif()
file(STRINGS "${OUTPUT}" lines REGEX "^count ${SCENE} ")
if(NOT lines)
  message(FATAL_ERROR "${OUTPUT}: no instruction counts of scene ${SCENE}")
endif()
set(failed FALSE)
foreach(line IN LISTS lines)
  # count SCENE MOTION TICKS loop SUM MAX every SUM MAX effects SUM MAX
  if(NOT line MATCHES "^count [^ ]+ ([^ ]+) ([0-9]+) loop ([0-9]+) ([0-9]+) every ([0-9]+) ([0-9]+) effects ([0-9]+) ([0-9]+)$")
    message(FATAL_ERROR "${OUTPUT}: bad line '${line}'")
  endif()
  set(motion ${CMAKE_MATCH_1})
  set(ticks ${CMAKE_MATCH_2})
  if(WHAT STREQUAL "loop")
    set(sum ${CMAKE_MATCH_3})
    set(worst ${CMAKE_MATCH_4})
  elseif(WHAT STREQUAL "every")
    set(sum ${CMAKE_MATCH_5})
    set(worst ${CMAKE_MATCH_6})
  elseif(WHAT STREQUAL "effects")
    set(sum ${CMAKE_MATCH_7})
    set(worst ${CMAKE_MATCH_8})
  else()
    message(FATAL_ERROR "check_budget.cmake: WHAT is loop, every or effects, not '${WHAT}'")
  endif()
  math(EXPR mean "${sum} / ${ticks}")
  if(DEFINED MEAN_BUDGET AND mean GREATER MEAN_BUDGET AND NOT motion MATCHES "^search_")
    set(failed TRUE)
    message("over: ${SCENE} with ${motion}: ${WHAT} mean ${mean} instructions a tick > ${MEAN_BUDGET}")
  endif()
  if(worst GREATER BUDGET)
    set(failed TRUE)
    message("over: ${SCENE} with ${motion}: ${WHAT} most expensive tick ${worst} instructions > ${BUDGET} (mean ${mean})")
  else()
    message("ok:   ${SCENE} with ${motion}: ${WHAT} most expensive tick ${worst} <= ${BUDGET} (mean ${mean})")
  endif()
endforeach()
if(failed)
  message(FATAL_ERROR "${SCENE}: over the budget for ${WHAT} (every tick ${BUDGET}, mean ${MEAN_BUDGET})")
endif()
