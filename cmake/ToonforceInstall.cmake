# SPDX-License-Identifier: Apache-2.0
# Install: what `cmake --install` puts where, in components, and the package
# config (find_package(toonforce)) and pkg-config files a program embedding toonforce uses.
#
#   component      what                                                     Debian package
#   runtime        bin/toonforce, share/toonforce (scenes, hand scripts,   toonforce
#                  motions, plot script), the udev rule, the limits.d
#                  snippet, the systemd unit template, docs
#   devel          headers and static libraries of effects, the hal seam,  toonforce-dev
#                  control, control_rt, host_sim, config, trace; the CMake
#                  package config; toonforce.pc; the examples' sources
#   falcon_devel   the Falcon backend (toonforce::hal_falcon, toonforce-falcon.pc)   toonforce-falcon-dev
#   gpio_devel     the GPIO backend (toonforce::hal_gpio, toonforce-gpio.pc)         toonforce-gpio-dev
#   omni_devel     the Omni backend, when this tree has it (toonforce::hal_omni)     toonforce-omni-dev
#
# Device backends are separate components, export sets and pkg-config files, so a program
# that embeds the effects and the loop needs neither libusb nor libgpiod (the link graph of
# the source tree, kept in the package): find_package(toonforce COMPONENTS falcon).
#
# Everything is relative to the install prefix, resolved when installing, so one build tree
# installs anywhere (cmake --install --prefix P) and CPack packages it for /usr. The files
# under etc/ are the exception handled in ToonforceInstallHost.cmake.in.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(TOONFORCE_INSTALL_CMAKEDIR "${CMAKE_INSTALL_LIBDIR}/cmake/toonforce" CACHE STRING
    "Where the CMake package config goes (relative to the prefix)")
# udev reads /usr/lib/udev/rules.d (and /usr/local/lib/udev/rules.d) for rules that packages
# and local installs ship, and /etc/udev/rules.d for the administrator's own, which override
# a shipped file of the same name (udev(7)). A package must not put files in the admin's
# directory, so the rule goes to <prefix>/lib/udev/rules.d: /usr/lib/udev/rules.d from the
# Debian package, /usr/local/lib/udev/rules.d from a default cmake --install; both are read.
# Not CMAKE_INSTALL_LIBDIR: udev never looks in a multiarch directory.
set(TOONFORCE_INSTALL_UDEVRULESDIR "lib/udev/rules.d" CACHE STRING
    "Where the udev rule goes (relative to the prefix)")
# systemd reads unit files from /usr/lib/systemd/system and /usr/local/lib/systemd/system
# (systemd.unit(5)); /etc/systemd/system is the administrator's, like /etc/udev/rules.d.
set(TOONFORCE_INSTALL_SYSTEMDUNITDIR "lib/systemd/system" CACHE STRING
    "Where the systemd unit template goes (relative to the prefix)")
set(TOONFORCE_INSTALL_DATADIR "${CMAKE_INSTALL_DATADIR}/toonforce")

# ---- libraries -------------------------------------------------------------------------------
# The public surface of the package: targets keep their in-tree names (toonforce::effects, ...)
# so a program builds the same way inside this tree and against an install.
set(_toonforce_core_libraries
  toonforce_effects toonforce_hal toonforce_control toonforce_control_rt toonforce_host_sim
  toonforce_config toonforce_trace)
set(_toonforce_core_headers
  effects/include hal/include control/include host_sim/include tools/config/include tools/trace/include)

# One entry per backend: component name | target | headers | pkg-config Requires | extra Libs.
set(_toonforce_backends
  "falcon|toonforce_hal_falcon|hal/falcon/include|libusb-1.0, nettle|"
  "gpio|toonforce_hal_gpio|hal/gpio/include|libgpiod|"
  "omni|toonforce_hal_omni|hal/omni/include|libusb-1.0, hidapi-hidraw|-ldl")

function(_toonforce_exportable target)
  string(REGEX REPLACE "^toonforce_" "" export_name "${target}")
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${export_name})
  get_target_property(type ${target} TYPE)
  if(type STREQUAL "STATIC_LIBRARY")
    # Position-independent, so a game engine's plugin (a shared object) can link them too.
    set_target_properties(${target} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  endif()
endfunction()

foreach(target IN LISTS _toonforce_core_libraries ITEMS toonforce_warnings)
  _toonforce_exportable(${target})
endforeach()
install(TARGETS ${_toonforce_core_libraries} toonforce_warnings
  EXPORT toonforceTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT devel
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
# Only the public headers: not a `detail/` directory, nor the headers no installed header
# includes that serve this tree's own programs (the explicit instantiations its libraries
# compile, `run`'s process split, the memory it shares with its server process, the watchers'
# clock). tests/install/consumer_test.cmake checks that every installed header's includes are
# installed too and that these are not.
set(_toonforce_internal_headers
  toonforce/effects/instantiations.hpp toonforce/control/process_split.hpp
  toonforce/control/server_channel.hpp toonforce/control/running_clock.hpp)
set(_toonforce_header_excludes PATTERN "detail" EXCLUDE)
foreach(header IN LISTS _toonforce_internal_headers)
  string(REPLACE "." "\\." header_regex "${header}")
  list(APPEND _toonforce_header_excludes REGEX "/${header_regex}$" EXCLUDE)
endforeach()
foreach(dir IN LISTS _toonforce_core_headers)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${dir}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
          COMPONENT devel FILES_MATCHING PATTERN "*.hpp" ${_toonforce_header_excludes})
endforeach()
install(EXPORT toonforceTargets NAMESPACE toonforce:: FILE toonforce-targets.cmake
        DESTINATION ${TOONFORCE_INSTALL_CMAKEDIR} COMPONENT devel)

# pkg-config files find their prefix from their own place (${pcfiledir}), so they stay right
# wherever the tree is installed or unpacked.
if(IS_ABSOLUTE "${CMAKE_INSTALL_LIBDIR}")
  message(FATAL_ERROR "CMAKE_INSTALL_LIBDIR must be relative to the prefix (it is ${CMAKE_INSTALL_LIBDIR})")
endif()
file(RELATIVE_PATH TOONFORCE_PC_TO_PREFIX "/p/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/p")
string(REGEX REPLACE "/$" "" TOONFORCE_PC_TO_PREFIX "${TOONFORCE_PC_TO_PREFIX}")
set(TOONFORCE_PC_LIBS "")
foreach(target IN ITEMS toonforce_config toonforce_trace toonforce_control_rt toonforce_host_sim
                        toonforce_control toonforce_effects)  # static: users before what they use
  string(APPEND TOONFORCE_PC_LIBS " -l${target}")
endforeach()
configure_file(${PROJECT_SOURCE_DIR}/cmake/package/toonforce.pc.in ${PROJECT_BINARY_DIR}/package/toonforce.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/package/toonforce.pc
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig COMPONENT devel)

set(TOONFORCE_BACKEND_COMPONENTS "")
foreach(entry IN LISTS _toonforce_backends)
  string(REPLACE "|" ";" fields "${entry}")
  list(GET fields 0 name)
  list(GET fields 1 target)
  list(GET fields 2 headers)
  list(GET fields 3 TOONFORCE_PC_BACKEND_REQUIRES)
  list(GET fields 4 TOONFORCE_PC_BACKEND_EXTRA_LIBS)
  if(NOT TARGET ${target})
    continue()  # a backend this tree does not have (yet)
  endif()
  list(APPEND TOONFORCE_BACKEND_COMPONENTS ${name})
  set(TOONFORCE_PC_BACKEND ${name})
  set(TOONFORCE_PC_BACKEND_LIB ${target})
  _toonforce_exportable(${target})
  install(TARGETS ${target} EXPORT toonforce_${name}_targets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT ${name}_devel
    INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${headers}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
          COMPONENT ${name}_devel FILES_MATCHING PATTERN "*.hpp" ${_toonforce_header_excludes})
  install(EXPORT toonforce_${name}_targets NAMESPACE toonforce:: FILE toonforce-${name}-targets.cmake
          DESTINATION ${TOONFORCE_INSTALL_CMAKEDIR} COMPONENT ${name}_devel)
  # The backend's part of the package config: its dependencies, then its targets.
  install(FILES ${PROJECT_SOURCE_DIR}/cmake/package/toonforce-${name}.cmake
          DESTINATION ${TOONFORCE_INSTALL_CMAKEDIR} COMPONENT ${name}_devel)
  configure_file(${PROJECT_SOURCE_DIR}/cmake/package/toonforce-backend.pc.in
                 ${PROJECT_BINARY_DIR}/package/toonforce-${name}.pc @ONLY)
  install(FILES ${PROJECT_BINARY_DIR}/package/toonforce-${name}.pc
          DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig COMPONENT ${name}_devel)
endforeach()

configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/package/toonforce-config.cmake.in
  ${PROJECT_BINARY_DIR}/package/toonforce-config.cmake
  INSTALL_DESTINATION ${TOONFORCE_INSTALL_CMAKEDIR})
# 0.x: the API may change between minor versions, so only the same minor version matches.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/package/toonforce-config-version.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/package/toonforce-config.cmake
              ${PROJECT_BINARY_DIR}/package/toonforce-config-version.cmake
        DESTINATION ${TOONFORCE_INSTALL_CMAKEDIR} COMPONENT devel)

# The examples' sources, to copy and start from.
install(DIRECTORY ${PROJECT_SOURCE_DIR}/examples/ DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples COMPONENT devel)

# ---- the program and its data ----------------------------------------------------------------
install(TARGETS toonforce RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT runtime)
# `run` execs its guardian from ../libexec/toonforce/ (control/src/process_split.cpp).
install(TARGETS toonforce-guardian RUNTIME DESTINATION ${CMAKE_INSTALL_LIBEXECDIR}/toonforce COMPONENT runtime)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/scenes/ DESTINATION ${TOONFORCE_INSTALL_DATADIR}/scenes
        COMPONENT runtime FILES_MATCHING PATTERN "*.toml" PATTERN "*.csv")
# `toonforce sim --plot` and `toonforce figures` run it (tools/sim/src/plot.cpp finds it here).
install(PROGRAMS ${PROJECT_SOURCE_DIR}/tools/plot_trace.py DESTINATION ${TOONFORCE_INSTALL_DATADIR}
        COMPONENT runtime)
install(FILES ${PROJECT_SOURCE_DIR}/README.md ${PROJECT_SOURCE_DIR}/LICENSE ${PROJECT_SOURCE_DIR}/THIRD-PARTY-NOTICES.md
        DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT runtime)
# Each Debian package's copyright file, machine-readable (DEP-5), where Debian policy 12.5 puts it:
# /usr/share/doc/PACKAGE/copyright, PACKAGE being the component's package name
# (cmake/ToonforcePackaging.cmake).
set(_toonforce_copyright ${PROJECT_SOURCE_DIR}/cmake/package/debian/copyright)
install(FILES ${_toonforce_copyright} DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/toonforce COMPONENT runtime)
install(FILES ${_toonforce_copyright} DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/toonforce-dev COMPONENT devel)
foreach(_backend IN LISTS TOONFORCE_BACKEND_COMPONENTS)
  install(FILES ${_toonforce_copyright} DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/toonforce-${_backend}-dev
          COMPONENT ${_backend}_devel)
endforeach()
if(TOONFORCE_PYTHON)
  install(FILES ${_toonforce_copyright} DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/python3-toonforce COMPONENT python)
endif()
install(DIRECTORY ${PROJECT_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR}
        COMPONENT runtime FILES_MATCHING PATTERN "*.md")
install(FILES ${PROJECT_SOURCE_DIR}/hal/falcon/udev/60-novint-falcon.rules
        DESTINATION ${TOONFORCE_INSTALL_UDEVRULESDIR} COMPONENT runtime)

# The limits.d snippet and the systemd unit template depend on the prefix the files are
# installed to (/etc for /usr; the paths in the unit), which is known only when installing:
# cmake --install --prefix P, or CPack, which installs with prefix /usr under DESTDIR.
configure_file(${PROJECT_SOURCE_DIR}/cmake/ToonforceInstallHost.cmake.in
               ${PROJECT_BINARY_DIR}/package/ToonforceInstallHost.cmake @ONLY)
install(SCRIPT ${PROJECT_BINARY_DIR}/package/ToonforceInstallHost.cmake COMPONENT runtime)
