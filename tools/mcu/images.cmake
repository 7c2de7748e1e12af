# SPDX-License-Identifier: Apache-2.0
# What the microcontroller images are, in one place for the host build (CMakeLists.txt), its
# tests (tests.cmake) and the cross build (firmware/CMakeLists.txt).
# One image per paper scene and one with all five; each plays every motion (more ticks
# compared with the host than the scene-motion pairs the scene files name).
set(TOONFORCE_MCU_SCENES wall realistic_friction slippery cartoon_wall cliff)
set(TOONFORCE_MCU_MOTIONS strike stroke crossing_fast crossing_slow)
# QEMU's -icount shift: each instruction advances the virtual clock 2^7 ns, 3.2 SysTick counts
# at 25 MHz, enough for the image to recover exact instruction counts (firmware/main.cpp).
set(TOONFORCE_MCU_ICOUNT_SHIFT 7)
# Each scene's image also plays that scene's searched inputs (`toonforce-lab report`'s search path),
# one motion per strike, written by `toonforce_mcu_gen strikes` into the build tree:
# search_SCENE_0 .. search_SCENE_{N-1}, each also as search_SCENE_K_late (with late ticks: rows
# left out). N is the report's kSearchStrikes (workloads.hpp); the generator refuses another.
set(TOONFORCE_MCU_STRIKE_COUNT 8)
foreach(_scene IN LISTS TOONFORCE_MCU_SCENES)
  set(TOONFORCE_MCU_STRIKES_${_scene})
  math(EXPR _last "${TOONFORCE_MCU_STRIKE_COUNT} - 1")
  foreach(_k RANGE ${_last})
    list(APPEND TOONFORCE_MCU_STRIKES_${_scene} search_${_scene}_${_k} search_${_scene}_${_k}_late)
  endforeach()
endforeach()
