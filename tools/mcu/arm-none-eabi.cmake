# SPDX-License-Identifier: Apache-2.0
# CMake toolchain file: bare-metal Arm Cortex-M with Debian's arm-none-eabi GCC, newlib and
# libstdc++ headers (packages gcc-arm-none-eabi, libnewlib-arm-none-eabi,
# libstdc++-arm-none-eabi-newlib). TOONFORCE_MCU_CPU picks the core:
#   cortex-m3   ARMv7-M, no FPU (QEMU mps2-an385): soft-float ABI, every float op a library call
#   cortex-m4f  ARMv7E-M with the single-precision FPU (QEMU mps2-an386): hard-float ABI
# C++ without exceptions, RTTI, thread-safe statics or atexit: none exists on the target.
# No start files (the image brings its own vector table and reset code) and newlib-nano.
# -mno-unaligned-access: every load and store the compiler emits is aligned to its size. By
# default GCC merges neighbouring narrow stores into one that may be unaligned (two bool members
# into a halfword store at an odd offset): an extra bus cycle on the M3 (TRM r2p1 3.3.1), and a
# UsageFault with CCR.UNALIGN_TRP set, which the images' start-up sets (firmware/startup.cpp).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
# CMake's compiler checks would link a program, which needs a linker script; a library will do.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

set(TOONFORCE_MCU_CPU "cortex-m3" CACHE STRING "Target core: cortex-m3 or cortex-m4f")
set_property(CACHE TOONFORCE_MCU_CPU PROPERTY STRINGS cortex-m3 cortex-m4f)
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES TOONFORCE_MCU_CPU)
if(TOONFORCE_MCU_CPU STREQUAL "cortex-m3")
  set(_toonforce_cpu_flags "-mcpu=cortex-m3 -mthumb -mfloat-abi=soft")
elseif(TOONFORCE_MCU_CPU STREQUAL "cortex-m4f")
  set(_toonforce_cpu_flags "-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard")
else()
  message(FATAL_ERROR "TOONFORCE_MCU_CPU must be cortex-m3 or cortex-m4f, not '${TOONFORCE_MCU_CPU}'")
endif()

set(_toonforce_cpu_flags "${_toonforce_cpu_flags} -mno-unaligned-access")

set(CMAKE_C_FLAGS_INIT "${_toonforce_cpu_flags} -ffunction-sections -fdata-sections")
set(CMAKE_CXX_FLAGS_INIT
    "${_toonforce_cpu_flags} -ffunction-sections -fdata-sections -fno-exceptions -fno-rtti -fno-threadsafe-statics -fno-use-cxa-atexit")
set(CMAKE_EXE_LINKER_FLAGS_INIT "${_toonforce_cpu_flags} --specs=nano.specs -nostartfiles -Wl,--gc-sections")

# Look for libraries and headers in the cross environment only, for programs on the host.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
