# SPDX-License-Identifier: Apache-2.0
# The firmware-style build's test run (cmake -P): the toonforce binary built with
# TOONFORCE_FIRMWARE=ON runs the servo loop on the simulated device in Q16.16, and refuses a
# floating-point scalar. Variables: BINARY, SOURCE_DIR, OUT_DIR.
foreach(var BINARY SOURCE_DIR OUT_DIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "firmware_run.cmake: ${var} is not set")
  endif()
endforeach()
file(MAKE_DIRECTORY "${OUT_DIR}")
set(stats "${OUT_DIR}/firmware_stats.json")
set(trace "${OUT_DIR}/firmware_trace.csv")
file(REMOVE "${stats}" "${trace}")

execute_process(
  COMMAND "${BINARY}" run --device sim --scene "${SOURCE_DIR}/scenes/slippery.toml" --duration 0.5
          --allow-non-rt --no-mlock --stats-json "${stats}" --trace "${trace}"
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
message("${out}${err}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the firmware build's run failed (exit ${rc})")
endif()
file(READ "${stats}" json)
string(JSON scalar GET "${json}" scalar)
string(JSON ticks GET "${json}" ticks)
string(JSON missed GET "${json}" missed)
string(JSON written GET "${json}" frames_written)
if(NOT scalar STREQUAL "q16.16")
  message(FATAL_ERROR "the firmware build ran the servo loop in ${scalar}, not q16.16")
endif()
math(EXPR deadlines "${ticks} + ${missed}")
if(NOT deadlines EQUAL 500)
  message(FATAL_ERROR "0.5 s at 1 kHz: ${ticks} ticks + ${missed} missed != 500 deadlines")
endif()
math(EXPR rows "${ticks} + 1")
if(NOT written EQUAL rows)
  message(FATAL_ERROR "${written} trace rows for ${ticks} ticks (expected ticks + 1)")
endif()

execute_process(
  COMMAND "${BINARY}" run --device sim --scene "${SOURCE_DIR}/scenes/slippery.toml" --duration 0.1 --scalar double
          --allow-non-rt --no-mlock
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0 OR NOT err MATCHES "firmware build")
  message(FATAL_ERROR "a firmware build must refuse --scalar double (exit ${rc}): ${out}${err}")
endif()
# The firmware-style build leaves the live viewer out entirely (TOONFORCE_VIEWER is never on
# with TOONFORCE_FIRMWARE): no `view` subcommand, no --view option.
execute_process(COMMAND "${BINARY}" view x.csv RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0)
  message(FATAL_ERROR "a firmware build has no viewer, yet `toonforce view` did not fail: ${out}${err}")
endif()
execute_process(COMMAND "${BINARY}" --help RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR "${out}" MATCHES "\n +view ")
  message(FATAL_ERROR "a firmware build's subcommands must not include view (exit ${rc}): ${out}${err}")
endif()
# Nor `report`: no build has it in toonforce (it is the lab's toonforce-lab, tools/CMakeLists.txt).
if("${out}" MATCHES "\n +report ")
  message(FATAL_ERROR "a firmware build's subcommands must not include report: ${out}")
endif()
execute_process(COMMAND "${BINARY}" run --help RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0 OR "${out}" MATCHES "--view")
  message(FATAL_ERROR "a firmware build's `toonforce run` must have no --view option (exit ${rc}): ${out}${err}")
endif()
message("firmware build: the servo loop ran ${ticks} ticks in q16.16; no viewer and no report in it")
