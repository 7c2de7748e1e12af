# SPDX-License-Identifier: Apache-2.0
# Runs one microcontroller image under qemu-system-arm and compares its forces with the
# host's `toonforce replay --scalar SCALAR` of each of its scenes and motions, bit for bit.
# Variables: QEMU MACHINE CPU SHIFT IMAGE TOONFORCE GEN SOURCE_DIR SCENES MOTIONS OUT_DIR
# (SCENES and MOTIONS comma-separated; a motion is NAME, scenes/motions/NAME.csv, or
# NAME=FILE); SCALAR (default q16.16) and SINE (replay --sine, as the image was generated with) and COVERAGE (a file for the start addresses of the code that
# ran, for the static bound's report: check_bound.py --covered) optional.
foreach(var QEMU MACHINE CPU SHIFT IMAGE TOONFORCE GEN SOURCE_DIR SCENES MOTIONS OUT_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "run_image.cmake: ${var} is not set")
  endif()
endforeach()
if(NOT DEFINED SCALAR)
  set(SCALAR q16.16)
endif()
set(sine_args)
if(SINE)
  set(sine_args --sine ${SINE})
endif()
string(REPLACE "," ";" SCENES "${SCENES}")
string(REPLACE "," ";" MOTIONS "${MOTIONS}")
file(MAKE_DIRECTORY "${OUT_DIR}")
set(target_out "${OUT_DIR}/target.txt")
file(REMOVE "${target_out}")

# -icount: the virtual clock advances 2^SHIFT ns per instruction, so the image's SysTick
# readings count instructions exactly (align and sleep off: no tie to the host's clock).
# Semihosting carries the output (into a file: by default QEMU writes it to its standard
# error, mixed with its own messages) and the exit status; no display, serial or monitor.
set(qemu_command "${QEMU}" -machine ${MACHINE} -cpu ${CPU} -display none -monitor none -serial none
  -chardev file,id=semihosting,path=${target_out}
  -semihosting-config enable=on,target=native,chardev=semihosting
  -icount shift=${SHIFT},align=off,sleep=off -kernel "${IMAGE}")
if(DEFINED COVERAGE)
  # Also which code ran: QEMU logs each translation block it runs (`-d exec,nochain`: every
  # one, not only those entered from outside a chain) on its standard output, and awk keeps
  # each start address once, into COVERAGE (wcet.py --covered reads it). Tens of millions of
  # lines, never stored: about 10 s more per image.
  file(REMOVE "${COVERAGE}")
  execute_process(
    COMMAND ${qemu_command} -d exec,nochain -D /dev/stdout
    COMMAND awk "/^Trace/ { split($4, a, \"/\"); if (!(a[2] in seen)) { seen[a[2]] = 1; print a[2] } }"
    OUTPUT_FILE "${COVERAGE}" ERROR_VARIABLE err RESULTS_VARIABLE results TIMEOUT 240)
  list(GET results 0 rc)
  set(out "")
else()
  execute_process(COMMAND ${qemu_command} OUTPUT_VARIABLE out ERROR_VARIABLE err RESULT_VARIABLE rc TIMEOUT 240)
endif()
if(EXISTS "${target_out}")
  file(READ "${target_out}" target_text)
else()
  set(target_text "")
endif()
if(NOT rc EQUAL 0)
  string(REGEX MATCHALL "(trap|error)[^\n]*" problems "${target_text}")
  message(FATAL_ERROR "the image failed under QEMU (exit ${rc}): ${problems}\n${out}${err}")
endif()
if(NOT target_text MATCHES "\ndone\n")
  message(FATAL_ERROR "the image did not finish: ${target_text}")
endif()

set(host_args)
foreach(scene IN LISTS SCENES)
  foreach(motion IN LISTS MOTIONS)
    # NAME (a bundled motion, scenes/motions/NAME.csv) or NAME=FILE (the searched inputs).
    if(motion MATCHES "^([^=]+)=(.+)$")
      set(motion "${CMAKE_MATCH_1}")
      set(motion_file "${CMAKE_MATCH_2}")
    else()
      set(motion_file "${SOURCE_DIR}/scenes/motions/${motion}.csv")
    endif()
    set(csv "${OUT_DIR}/replay_${scene}_${motion}.csv")
    execute_process(
      COMMAND "${TOONFORCE}" replay --scene "${SOURCE_DIR}/scenes/${scene}.toml"
              --input "${motion_file}" --output "${csv}" --scalar ${SCALAR} ${sine_args} --quiet
      RESULT_VARIABLE rc ERROR_VARIABLE err)
    if(NOT rc EQUAL 0)
      message(FATAL_ERROR "toonforce replay of ${scene} with ${motion} failed: ${err}")
    endif()
    list(APPEND host_args --host "${scene}/${motion}=${csv}")
  endforeach()
endforeach()

execute_process(COMMAND "${GEN}" compare --scalar ${SCALAR} --target "${target_out}" ${host_args}
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
message("${out}${err}")
string(REGEX MATCHALL "(calibration|count|stack|sizeof)[^\n]*" figures "${target_text}")
string(REPLACE ";" "\n" figures "${figures}")
message("${figures}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the image's forces differ from the host's replay")
endif()
