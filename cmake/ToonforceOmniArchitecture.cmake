# SPDX-License-Identifier: Apache-2.0
# The Omni backend's architecture check: OpenHaptics for Linux is 64-bit x86-64,
# and on 32-bit x86 the vendor's headers declare the HD API __stdcall, while our own
# declarations (hal/omni hd_api.hpp) are the plain cdecl of 64-bit Linux: through a 32-bit
# libHD every call would leave the stack corrupted. So a 32-bit x86 build is refused here, at
# configure time, before anything is compiled. Other 32-bit targets (ARM boards running the GPIO
# side) build: no OpenHaptics exists for them, and --device omni says that it is not installed.
# A function of its arguments, so tests/omni/omni_architecture_check.cmake can call it with
# the values of a 32-bit x86 target on this 64-bit machine.
function(toonforce_check_omni_architecture pointer_size processor)
  if(pointer_size EQUAL 4 AND processor MATCHES "^(i[3-6]86|x86|X86|AMD64|amd64|x86_64)$")
    message(FATAL_ERROR
      "toonforce refuses a 32-bit x86 build of the Omni backend (hal/omni): OpenHaptics' headers "
      "declare the HD API __stdcall on 32-bit x86, toonforce calls it with the cdecl convention of "
      "64-bit Linux, and every call would corrupt the stack. OpenHaptics for Linux is 64-bit: "
      "configure for x86-64 (no -m32, a 64-bit toolchain file).")
  elseif(pointer_size EQUAL 4)
    message(STATUS "hal/omni on 32-bit ${processor}: builds, but OpenHaptics exists for x86-64 only "
                   "(--device omni will say it is not installed)")
  endif()
endfunction()
