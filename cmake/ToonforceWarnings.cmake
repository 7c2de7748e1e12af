# SPDX-License-Identifier: Apache-2.0
# Warnings as an INTERFACE target, linked privately by every toonforce target (not global
# add_compile_options, so third-party code is not held to them).
# The options are BUILD_INTERFACE only: the installed static libraries name this target as a
# link-only dependency (CMake 3.25 exports PRIVATE links of static libraries), so the package
# exports it too, empty, and a program built against the package is never held to our flags.
set(_toonforce_warning_flags
  -Wall -Wextra -Wpedantic -Wconversion -Wsign-conversion -Wshadow -Wold-style-cast
  -Wnon-virtual-dtor -Wcast-align -Woverloaded-virtual -Wnull-dereference -Wdouble-promotion
  -Wimplicit-fallthrough
  $<$<BOOL:${TOONFORCE_WERROR}>:-Werror>)
add_library(toonforce_warnings INTERFACE)
add_library(toonforce::warnings ALIAS toonforce_warnings)
target_compile_options(toonforce_warnings INTERFACE "$<BUILD_INTERFACE:${_toonforce_warning_flags}>")
