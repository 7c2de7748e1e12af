# SPDX-License-Identifier: Apache-2.0
# Fails if anything in a Q16.16 image could set the APSR's Q bit besides the saturation flag's
# own `ssat rX, #1, rY` (math/fixed.hpp keeps the sticky flag there on an Armv7-M core): a
# compiler's clamp compiled to SSAT or USAT, or an MSR writing the flags, would raise or clear
# the flag without a saturation. The flag is cleared two ways only: a tick's start writes zero
# (`movs rX, #0` then `msr APSR_nzcvq, rX`, math/fixed.hpp's reset_saturation_flag), and
# take_fixed_saturated writes the APSR back with only Q cleared (`bic rX, rY, #0x8000000` then the
# MSR). Names each other instruction's function. Variables: OBJDUMP IMAGE.
foreach(var OBJDUMP IMAGE)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "check_q_bit.cmake: ${var} is not set")
  endif()
endforeach()
execute_process(COMMAND "${OBJDUMP}" -d -C --no-show-raw-insn "${IMAGE}" OUTPUT_VARIABLE disassembly RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${OBJDUMP} failed on ${IMAGE}")
endif()
string(REPLACE ";" "," disassembly "${disassembly}")  # keep CMake lists out of C++ names
string(REPLACE "\n" ";" lines "${disassembly}")
set(current "")
set(previous "")
set(flag_sets 0)
set(clears 0)
set(resets 0)
set(others "")
foreach(line IN LISTS lines)
  if(line MATCHES "^[0-9a-f]+ <(.*)>:$")
    set(current "${CMAKE_MATCH_1}")
  elseif(line MATCHES "\tssat[ \t]+[a-z0-9]+, #1, ")
    math(EXPR flag_sets "${flag_sets} + 1")
  elseif(line MATCHES "\tmsr[ \t]+[A-Za-z]+_[a-z]+, ([a-z0-9]+)$")
    # The flag's clear: the APSR written back with only bit 27 (Q) cleared.
    set(register "${CMAKE_MATCH_1}")
    if(previous MATCHES "\tbic([.]w)?[ \t]+${register}, [a-z0-9]+, #134217728")
      math(EXPR clears "${clears} + 1")
    elseif(previous MATCHES "\tmovs[ \t]+${register}, #0$")
      math(EXPR resets "${resets} + 1")
    else()
      list(APPEND others "${current}: ${line}")
    endif()
  elseif(line MATCHES "\t(ssat|usat|ssat16|usat16|qadd|qsub|qdadd|qdsub|msr)[ \t.]")
    list(APPEND others "${current}: ${line}")
  endif()
  set(previous "${line}")
endforeach()
if(others)
  string(REPLACE ";" "\n  " others "${others}")
  message(FATAL_ERROR "${IMAGE}: instructions that may set or clear the Q bit besides the saturation flag's:\n  ${others}")
endif()
message("${IMAGE}: the Q bit is set only by the saturation flag (${flag_sets} SSAT #1) and cleared only at a tick's start (${resets} MSR of zero) or when it is taken (${clears} MSR)")
