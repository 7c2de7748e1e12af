# SPDX-License-Identifier: Apache-2.0
# Fails if a Q16.16 image links any floating-point helper of the Arm run-time ABI: the
# __aeabi_d* / __aeabi_f* functions (RTABI 4.1.2; libgcc also names them __adddf3,
# __fixdfsi, ...), through which an FPU-less core does every float and double operation.
# On failure it names the image's functions that call them (from the disassembly), so the
# source of each is plain. Variables: NM OBJDUMP IMAGE.
foreach(var NM OBJDUMP IMAGE)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "check_no_float.cmake: ${var} is not set")
  endif()
endforeach()
execute_process(COMMAND "${NM}" --defined-only "${IMAGE}" OUTPUT_VARIABLE symbols RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${NM} failed on ${IMAGE}")
endif()
string(REGEX MATCHALL "[ \t](__aeabi_[df][a-z0-9_]*|__[a-z]+[sd]f[23]?|__[a-z]+[sd]fsi|__float[a-z]*[sd]f)\n" helpers "${symbols}")
list(TRANSFORM helpers STRIP)
list(REMOVE_DUPLICATES helpers)
list(SORT helpers)
if(NOT helpers)
  message("${IMAGE}: no floating-point helper linked")
  return()
endif()

# Which functions call them: walk the disassembly, remembering the enclosing function.
execute_process(COMMAND "${OBJDUMP}" -d -C --no-show-raw-insn "${IMAGE}" OUTPUT_VARIABLE disassembly)
string(REPLACE ";" "," disassembly "${disassembly}")  # keep CMake lists out of C++ names
string(REPLACE "\n" ";" lines "${disassembly}")
set(current "")
set(callers "")
foreach(line IN LISTS lines)
  if(line MATCHES "^[0-9a-f]+ <(.*)>:$")
    set(current "${CMAKE_MATCH_1}")
  elseif(line MATCHES "\tb(l|\\.w|)[ \t]+[0-9a-f]+ <(__aeabi_[df][a-z0-9_]*|__[a-z]+[sd]f[23si]*)>")
    if(NOT current MATCHES "^(__aeabi_|__[a-z]+[sd]f)")  # the helpers' own internal calls
      list(APPEND callers "${current}")
    endif()
  endif()
endforeach()
list(REMOVE_DUPLICATES callers)
string(REPLACE ";" "\n  " callers "${callers}")
string(REPLACE ";" " " helpers "${helpers}")
message(FATAL_ERROR "${IMAGE} links floating-point helpers: ${helpers}\ncalled from:\n  ${callers}")
