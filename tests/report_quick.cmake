# SPDX-License-Identifier: Apache-2.0
# The short form of the reports CI runs:
# `toonforce-lab report all --quick` into a scratch directory, then each document must have its
# sections (a report that stopped half-way, or wrote nothing, fails). The numbers are not
# judged here (timings never are in tests); the budget and scenario tests check what can be.
#   cmake -DBINARY=toonforce -DROOT=source -DOUT=dir -P report_quick.cmake
file(REMOVE_RECURSE ${OUT})
file(MAKE_DIRECTORY ${OUT})
# The generated parts of the performance pages go between the markers of existing files.
file(COPY ${ROOT}/docs/performance/tick.md ${ROOT}/docs/performance/precision.md DESTINATION ${OUT}/performance)
execute_process(COMMAND ${BINARY} report all --quick --no-callgrind --no-plot --out ${OUT} --root ${ROOT}
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "report all --quick failed (${rc}):\n${out}\n${err}")
endif()
foreach(pair "performance/tick.md|## Effect computations" "performance/precision.md|## Error against run time"
             "STABILITY.md|## How a point is classified" "STABILITY.md|### Stiffness and servo period")
  string(REPLACE "|" ";" parts "${pair}")
  list(GET parts 0 doc)
  list(GET parts 1 heading)
  file(READ ${OUT}/${doc} text)
  string(FIND "${text}" "${heading}" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "${doc} has no '${heading}' after report all --quick:\n${out}\n${err}")
  endif()
endforeach()
message(STATUS "report all --quick wrote ${OUT}/performance/ and ${OUT}/STABILITY.md")
