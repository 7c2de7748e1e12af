# SPDX-License-Identifier: Apache-2.0
# cmake -DPOINTER_SIZE=4|8 -DPROCESSOR=... -P omni_architecture_check.cmake: runs the Omni
# backend's configure-time architecture check for another target (tests/omni/CMakeLists.txt).
include(${CMAKE_CURRENT_LIST_DIR}/../../cmake/ToonforceOmniArchitecture.cmake)
toonforce_check_omni_architecture("${POINTER_SIZE}" "${PROCESSOR}")
message(STATUS "architecture accepted: ${POINTER_SIZE}-byte pointers, ${PROCESSOR}")
