# SPDX-License-Identifier: Apache-2.0
# CTest install_consumer: installs this build tree into a temporary prefix, moves the
# prefix elsewhere (the package must be relocatable), then uses it as a program embedding
# toonforce would:
#   1. the layout: every file where ToonforceInstall.cmake says, nothing pointing back into the
#      source or build tree, the unit and the limits snippet as generated for this prefix;
#   2. the installed binary finds the installed scenes and hand scripts (toonforce figures);
#   3. find_package(toonforce): builds the installed examples with toonforce's warnings (and
#      -Werror under CI) and runs them: compose_scene checks its equilibria itself;
#      run_scene_file must keep the handle at the realistic wall and throw it off the cartoon
#      wall (the paper's figures 2-3), in simulated time and once under the real-time runner;
#      scene_with_own_effect reads its own [[magnet]] effect from a scene file (its passivity
#      budget, trace columns and file:line:key errors), and the installed toonforce, which
#      does not know that effect, refuses the file by name;
#   4. find_package(toonforce COMPONENTS falcon gpio omni): tests/install/backends, run;
#   5. pkg-config: the examples and the backends consumer compiled with nothing but
#      `c++ $(pkg-config --cflags --libs ...)`, and run;
#   6. systemd-analyze verify on the installed unit template (an instance of it).
# The same compiler and flags as this build (sanitizers included: the installed libraries are
# instrumented too). Parameters (-D): SOURCE_DIR BUILD_DIR WORK_DIR GENERATOR MAKE_PROGRAM CXX
# CXX_FLAGS EXE_LINKER_FLAGS BUILD_TYPE PKG_CONFIG SYSTEMD_ANALYZE.
cmake_minimum_required(VERSION 3.25)

function(run_step what)
  cmake_parse_arguments(ARG "" "WORKING_DIRECTORY;OUTPUT" "COMMAND" ${ARGN})
  if(NOT ARG_WORKING_DIRECTORY)
    set(ARG_WORKING_DIRECTORY "${WORK_DIR}")
  endif()
  execute_process(COMMAND ${ARG_COMMAND} WORKING_DIRECTORY "${ARG_WORKING_DIRECTORY}"
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    string(REPLACE ";" " " shown "${ARG_COMMAND}")
    message(FATAL_ERROR "${what} failed (${rc}):\n  ${shown}\n${out}\n${err}")
  endif()
  message(STATUS "${what}: ok")
  if(ARG_OUTPUT)
    set(${ARG_OUTPUT} "${out}" PARENT_SCOPE)
  endif()
endfunction()

function(expect condition_text)
  if(NOT (${ARGN}))
    message(FATAL_ERROR "expected: ${condition_text}")
  endif()
endfunction()

file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
set(staging "${WORK_DIR}/staging")
set(prefix "${WORK_DIR}/moved/prefix")

# ---- install, then move -------------------------------------------------------------------------
run_step("cmake --install" COMMAND "${CMAKE_COMMAND}" --install "${BUILD_DIR}" --prefix "${staging}")
file(MAKE_DIRECTORY "${WORK_DIR}/moved")
file(RENAME "${staging}" "${prefix}")

# ---- 1. layout ----------------------------------------------------------------------------------
file(GLOB libdir_candidates LIST_DIRECTORIES true "${prefix}/lib*/cmake/toonforce")
list(LENGTH libdir_candidates n)
expect("one lib*/cmake/toonforce directory, found ${libdir_candidates}" n EQUAL 1)
get_filename_component(libdir "${libdir_candidates}/../.." ABSOLUTE)
foreach(file IN ITEMS
    bin/toonforce libexec/toonforce/toonforce-guardian
    include/toonforce/effects/scene.hpp include/toonforce/math/fixed.hpp include/toonforce/common/result.hpp
    include/toonforce/hal/device.hpp include/toonforce/control/servo_loop.hpp
    include/toonforce/control/realtime_runner.hpp include/toonforce/host_sim/sim_driver.hpp
    include/toonforce/config/scene_file.hpp include/toonforce/trace/trace_writer.hpp
    include/toonforce/hal/falcon/falcon.hpp include/toonforce/hal/gpio/gpio_session.hpp
    include/toonforce/hal/omni/omni_device.hpp
    share/toonforce/scenes/wall.toml share/toonforce/scenes/cartoon_wall.toml
    share/toonforce/scenes/hands/strike.toml share/toonforce/scenes/motions/strike.csv
    share/toonforce/plot_trace.py
    share/doc/toonforce/DEPLOY.md share/doc/toonforce/examples/CMakeLists.txt
    lib/udev/rules.d/60-novint-falcon.rules lib/systemd/system/toonforce@.service
    etc/security/limits.d/toonforce.conf)
  expect("${prefix}/${file} installed" EXISTS "${prefix}/${file}")
endforeach()
foreach(file IN ITEMS
    libtoonforce_effects.a libtoonforce_control.a libtoonforce_control_rt.a libtoonforce_host_sim.a
    libtoonforce_config.a libtoonforce_trace.a libtoonforce_hal_falcon.a libtoonforce_hal_gpio.a
    libtoonforce_hal_omni.a cmake/toonforce/toonforce-omni.cmake pkgconfig/toonforce-omni.pc
    cmake/toonforce/toonforce-config.cmake cmake/toonforce/toonforce-config-version.cmake
    cmake/toonforce/toonforce-falcon.cmake cmake/toonforce/toonforce-gpio.cmake
    pkgconfig/toonforce.pc pkgconfig/toonforce-falcon.pc pkgconfig/toonforce-gpio.pc)
  expect("${libdir}/${file} installed" EXISTS "${libdir}/${file}")
endforeach()
# Only the public headers: each installed header's own includes are installed too (a header a
# public one includes is public), and the internal ones cmake/ToonforceInstall.cmake names are not.
file(GLOB_RECURSE installed_headers "${prefix}/include/toonforce/*.hpp")
list(LENGTH installed_headers n)
expect("headers installed under ${prefix}/include/toonforce (found ${n})" n GREATER 40)
foreach(header IN LISTS installed_headers)
  file(STRINGS "${header}" includes REGEX "^#include \"toonforce/")
  foreach(line IN LISTS includes)
    string(REGEX REPLACE "^#include \"([^\"]+)\".*" "\\1" included "${line}")
    expect("${header} includes ${included}, which is installed" EXISTS "${prefix}/include/${included}")
  endforeach()
  expect("no detail/ header installed (${header})" NOT header MATCHES "/detail/")
endforeach()
foreach(file IN ITEMS toonforce/effects/instantiations.hpp toonforce/control/process_split.hpp
                      toonforce/control/server_channel.hpp toonforce/control/running_clock.hpp)
  expect("the internal ${file} is not installed" NOT EXISTS "${prefix}/include/${file}")
endforeach()
# The package files must not lean on the trees this was built from (it was moved anyway).
file(GLOB_RECURSE package_files "${libdir}/cmake/toonforce/*" "${libdir}/pkgconfig/*")
foreach(file IN LISTS package_files)
  file(READ "${file}" text)
  foreach(tree IN ITEMS "${SOURCE_DIR}" "${BUILD_DIR}" "${staging}")
    string(FIND "${text}" "${tree}" at)
    expect("${file} does not mention ${tree}" at EQUAL -1)
  endforeach()
endforeach()
file(READ "${prefix}/etc/security/limits.d/toonforce.conf" installed_limits)
file(READ "${SOURCE_DIR}/tools/deploy/toonforce-limits.conf" source_limits)
expect("the limits snippet installed as it is in tools/deploy" installed_limits STREQUAL source_limits)
# The unit was written for the prefix it was installed to (before the move).
file(READ "${prefix}/lib/systemd/system/toonforce@.service" unit)
string(FIND "${unit}" "ExecStart=${staging}/bin/toonforce run " at)
expect("the unit runs ${staging}/bin/toonforce" NOT at EQUAL -1)
string(FIND "${unit}" "Environment=TOONFORCE_SCENE=${staging}/share/toonforce/scenes/%i.toml" at)
expect("the unit's default scene is the installed one" NOT at EQUAL -1)

# ---- 2. the installed binary finds its own data ---------------------------------------------
# From a directory without scenes/: toonforce figures must find the installed scenes and hand
# scripts (and the plot script) beside the binary, not in the source tree.
file(MAKE_DIRECTORY "${WORK_DIR}/figures")
run_step("installed toonforce figures" COMMAND "${prefix}/bin/toonforce" figures --out "${WORK_DIR}/figures"
         OUTPUT figures_out)
string(FIND "${figures_out}" "scenes and hand scripts from ${prefix}/share/toonforce\n" at)
expect("toonforce figures used the installed data:\n${figures_out}" NOT at EQUAL -1)
expect("toonforce figures wrote fig3_cartoon_wall.csv" EXISTS "${WORK_DIR}/figures/fig3_cartoon_wall.csv")

# The installed run finds its guardian program (../libexec/toonforce from bin/) and runs.
run_step("installed toonforce run" COMMAND "${prefix}/bin/toonforce" run --device sim
         --scene "${prefix}/share/toonforce/scenes/wall.toml" --duration 0.2 --allow-non-rt --no-mlock --quiet
         OUTPUT installed_run_out)

# ---- 3. find_package: the examples --------------------------------------------------------------
separate_arguments(cxx_flags UNIX_COMMAND "${CXX_FLAGS}")
set(configure_common -G "${GENERATOR}" -DCMAKE_MAKE_PROGRAM=${MAKE_PROGRAM} -DCMAKE_CXX_COMPILER=${CXX}
    -DCMAKE_BUILD_TYPE=${BUILD_TYPE} "-DCMAKE_CXX_FLAGS=${CXX_FLAGS}" "-DCMAKE_EXE_LINKER_FLAGS=${EXE_LINKER_FLAGS}"
    "-DCMAKE_PREFIX_PATH=${prefix}")
run_step("configure the installed examples (find_package)"
  COMMAND "${CMAKE_COMMAND}" -S "${prefix}/share/doc/toonforce/examples" -B "${WORK_DIR}/examples"
          ${configure_common} -DTOONFORCE_EXAMPLES_WARNINGS=ON)
run_step("build the examples" COMMAND "${CMAKE_COMMAND}" --build "${WORK_DIR}/examples" -j 2)
run_step("compose_scene (checks its own equilibria)" COMMAND "${WORK_DIR}/examples/compose_scene" OUTPUT out)
message("${out}")

# The highest point the handle reaches after striking the floor at z = 0: the realistic wall
# keeps it there (an undamped spring gives back a fraction of a millimetre before the hand's
# damping and press settle it: 0.17 mm in docs/FIGURES.md), the cartoon wall's recoil throws it
# several millimetres out (6.1 mm there).
function(highest_after_strike program scene out_var)
  run_step("${program} ${scene}.toml" COMMAND "${program}" "${prefix}/share/toonforce/scenes/${scene}.toml"
           "${prefix}/share/toonforce/scenes/hands/strike.toml" ${ARGN} OUTPUT out)
  message("${out}")
  if(NOT out MATCHES "highest point after it: z = (-?[0-9.]+) mm")
    message(FATAL_ERROR "${program}: no 'highest point' line in:\n${out}")
  endif()
  set(${out_var} ${CMAKE_MATCH_1} PARENT_SCOPE)
endfunction()
function(check_strikes program)
  highest_after_strike("${program}" wall wall_mm ${ARGN})
  highest_after_strike("${program}" cartoon_wall cartoon_mm ${ARGN})
  expect("the realistic wall keeps the handle within 1 mm of the surface (highest ${wall_mm} mm)" wall_mm LESS 1)
  expect("the cartoon wall throws the handle out by more than 3 mm (highest ${cartoon_mm} mm)" cartoon_mm GREATER 3)
endfunction()
check_strikes("${WORK_DIR}/examples/run_scene_file")
# Under the real-time runner (control_rt): whatever the timing of this machine, the run must
# start and end cleanly (a hypervisor stall may latch the watchdog: exit 1 is accepted then).
execute_process(COMMAND "${WORK_DIR}/examples/run_scene_file" "${prefix}/share/toonforce/scenes/wall.toml"
                        "${prefix}/share/toonforce/scenes/hands/strike.toml" --realtime --no-mlock
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
message("${out}${err}")
expect("run_scene_file --realtime exits 0 or 1 (got ${rc})" rc EQUAL 0 OR rc EQUAL 1)
string(FIND "${out}" "real time: " at)
expect("run_scene_file --realtime reports its timing" NOT at EQUAL -1)

# An effect the library does not know, from a scene file by its key.
set(examples_data "${prefix}/share/doc/toonforce/examples/scenes")
function(check_own_effect program)
  run_step("${program} magnet.toml" COMMAND "${program}" "${examples_data}/magnet.toml" "${examples_data}/visit_magnet.toml"
           --trace "${WORK_DIR}/magnet.csv" OUTPUT out)
  message("${out}")
  # The program checks its own physics (captured, budget held, exceeded without the controller);
  # here: the trace carries the effect's values under its key, beside the library's.
  file(STRINGS "${WORK_DIR}/magnet.csv" header LIMIT_COUNT 1)
  string(FIND "${header}" ",surface1.contact,surface1.impact_t,magnet1.captured,magnet1.distance" at)
  expect("the trace has the magnet's columns after the surface's: ${header}" NOT at EQUAL -1)
  execute_process(COMMAND "${program}" "${examples_data}/magnet_typo.toml" "${examples_data}/visit_magnet.toml"
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  expect("a typo in the example's own table exits 2 (got ${rc})" rc EQUAL 2)
  string(FIND "${err}" "magnet_typo.toml:18: magnet[1]: unknown key 'stifness' (did you mean 'stiffness'?)" at)
  expect("the typo is named by file, line and key:\n${err}" NOT at EQUAL -1)
endfunction()
check_own_effect("${WORK_DIR}/examples/scene_with_own_effect")
execute_process(COMMAND "${prefix}/bin/toonforce" sim --scene "${examples_data}/magnet.toml"
                        --script "${examples_data}/visit_magnet.toml" --trace "${WORK_DIR}/refused.csv"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
string(FIND "${err}" "magnet.toml:16: unknown effect [[magnet]]" at)
expect("toonforce sim refuses the example's effect by name (rc ${rc}):\n${err}" NOT rc EQUAL 0 AND NOT at EQUAL -1)

# ---- 4. find_package with backend components ----------------------------------------------------
run_step("configure the backends consumer (find_package COMPONENTS falcon gpio omni)"
  COMMAND "${CMAKE_COMMAND}" -S "${SOURCE_DIR}/tests/install/backends" -B "${WORK_DIR}/backends" ${configure_common})
run_step("build the backends consumer" COMMAND "${CMAKE_COMMAND}" --build "${WORK_DIR}/backends")
run_step("backends" COMMAND "${WORK_DIR}/backends/backends" "${prefix}/lib/udev/rules.d/60-novint-falcon.rules")

# ---- 5. pkg-config ------------------------------------------------------------------------------
set(ENV{PKG_CONFIG_PATH} "${libdir}/pkgconfig")
function(pkg_config_build name source)
  run_step("pkg-config ${ARGN}" COMMAND "${PKG_CONFIG}" --cflags --libs ${ARGN} OUTPUT flags)
  string(STRIP "${flags}" flags)
  separate_arguments(flags UNIX_COMMAND "${flags}")
  run_step("c++ ${source} with pkg-config flags"
    COMMAND "${CXX}" -std=c++20 ${cxx_flags} "${source}" -o "${WORK_DIR}/pkg-config/${name}" ${flags})
endfunction()
file(MAKE_DIRECTORY "${WORK_DIR}/pkg-config")
pkg_config_build(compose_scene "${prefix}/share/doc/toonforce/examples/compose_scene.cpp" toonforce)
pkg_config_build(run_scene_file "${prefix}/share/doc/toonforce/examples/run_scene_file.cpp" toonforce)
pkg_config_build(scene_with_own_effect "${prefix}/share/doc/toonforce/examples/scene_with_own_effect.cpp" toonforce)
pkg_config_build(backends "${SOURCE_DIR}/tests/install/backends/backends.cpp" toonforce-falcon toonforce-gpio
                 toonforce-omni)
run_step("compose_scene (pkg-config)" COMMAND "${WORK_DIR}/pkg-config/compose_scene")
check_strikes("${WORK_DIR}/pkg-config/run_scene_file")
check_own_effect("${WORK_DIR}/pkg-config/scene_with_own_effect")
run_step("backends (pkg-config)"
  COMMAND "${WORK_DIR}/pkg-config/backends" "${prefix}/lib/udev/rules.d/60-novint-falcon.rules")

# ---- 6. the unit template -----------------------------------------------------------------------
# verify needs an instance and an executable ExecStart: write the unit as installed, with the
# binary's path moved along with the prefix.
file(MAKE_DIRECTORY "${WORK_DIR}/units")
string(REPLACE "${staging}/" "${prefix}/" moved_unit "${unit}")
file(WRITE "${WORK_DIR}/units/toonforce@.service" "${moved_unit}")
file(CREATE_LINK "toonforce@.service" "${WORK_DIR}/units/toonforce@wall.service" SYMBOLIC)
execute_process(COMMAND "${SYSTEMD_ANALYZE}" verify --man=no "${WORK_DIR}/units/toonforce@wall.service"
                RESULT_VARIABLE rc OUTPUT_VARIABLE verify_out ERROR_VARIABLE verify_err)
# systemd-analyze exits 0 on directives it ignores; it must have nothing to say at all.
string(LENGTH "${verify_out}${verify_err}" said)
expect("systemd-analyze verify accepts the unit silently; it exited ${rc} and said:\n${verify_out}${verify_err}"
       rc EQUAL 0 AND said EQUAL 0)
message(STATUS "systemd-analyze verify toonforce@wall.service: ok")

message(STATUS "install_consumer: all checks passed")
