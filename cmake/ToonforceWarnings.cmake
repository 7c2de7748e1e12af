# Warnings as an INTERFACE target, linked privately by every toonforce target (not global
# add_compile_options, so third-party code is not held to them).
add_library(toonforce_warnings INTERFACE)
add_library(toonforce::warnings ALIAS toonforce_warnings)
target_compile_options(toonforce_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wconversion -Wsign-conversion -Wshadow -Wold-style-cast
  -Wnon-virtual-dtor -Wcast-align -Woverloaded-virtual -Wnull-dereference -Wdouble-promotion
  -Wimplicit-fallthrough
  $<$<BOOL:${TOONFORCE_WERROR}>:-Werror>)
