# SPDX-License-Identifier: Apache-2.0
# CTest debian_package: builds the Debian packages of this build tree with CPack and
# checks what dpkg would install from them: the program, scenes, udev rule, limits snippet
# (a conffile) and unit template in `toonforce`, written for /usr and /etc; headers, libraries
# and package files in `toonforce-dev`; each backend in its own -dev package depending on it;
# the maintainer scripts valid shell; no file in two packages; no file of the lab in any
# (tests/install/check_install_files.py --listing). Parameters (-D): BUILD_DIR WORK_DIR CPACK
# DPKG_DEB VERSION PYTHON CHECK_FILES (that script).
cmake_minimum_required(VERSION 3.25)

function(expect condition_text)
  if(NOT (${ARGN}))
    message(FATAL_ERROR "expected: ${condition_text}")
  endif()
endfunction()

function(run what out_var)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    string(REPLACE ";" " " shown "${ARGN}")
    message(FATAL_ERROR "${what} failed (${rc}):\n  ${shown}\n${out}\n${err}")
  endif()
  set(${out_var} "${out}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
run("cpack -G DEB" cpack_out "${CPACK}" --config "${BUILD_DIR}/CPackConfig.cmake" -G DEB -B "${WORK_DIR}")
message(STATUS "cpack:\n${cpack_out}")

# Each package: its files (./usr/..., directories left out), fields and control files.
set(all_files "")
foreach(package IN ITEMS toonforce toonforce-dev toonforce-falcon-dev toonforce-gpio-dev toonforce-omni-dev)
  file(GLOB deb "${WORK_DIR}/${package}_${VERSION}_*.deb")
  list(LENGTH deb n)
  expect("one ${package}_${VERSION}_<arch>.deb, found '${deb}'" n EQUAL 1)
  run("dpkg-deb -c ${package}" listing "${DPKG_DEB}" --contents "${deb}")
  string(REGEX MATCHALL "\\./[^\n]*[^/\n]\n" entries "${listing}")
  set(files "")
  foreach(entry IN LISTS entries)
    string(STRIP "${entry}" entry)
    string(REGEX REPLACE " -> .*$" "" entry "${entry}")  # symbolic links: their own name
    list(APPEND files "${entry}")
  endforeach()
  foreach(file IN LISTS files)
    list(FIND all_files "${file}" other)
    expect("${file} in one package only (${package} and another)" other EQUAL -1)
  endforeach()
  list(APPEND all_files ${files})
  set(files_${package} "${files}")
  run("dpkg-deb -f ${package}" fields_${package} "${DPKG_DEB}" --field "${deb}")
  file(MAKE_DIRECTORY "${WORK_DIR}/control/${package}")
  run("dpkg-deb -e ${package}" ignored "${DPKG_DEB}" --control "${deb}" "${WORK_DIR}/control/${package}")
  set(deb_${package} "${deb}")
endforeach()

function(expect_files package)
  foreach(file IN LISTS ARGN)
    list(FIND files_${package} "${file}" at)
    expect("${file} in ${package}; it has:\n${files_${package}}" NOT at EQUAL -1)
  endforeach()
endfunction()
function(expect_field package text)
  string(FIND "${fields_${package}}" "${text}" at)
  expect("'${text}' in the control fields of ${package}:\n${fields_${package}}" NOT at EQUAL -1)
endfunction()

# ---- toonforce: the program and what a host needs ----------------------------------------------
expect_files(toonforce ./usr/bin/toonforce ./usr/libexec/toonforce/toonforce-guardian ./usr/lib/udev/rules.d/60-novint-falcon.rules
  ./etc/security/limits.d/toonforce.conf ./usr/lib/systemd/system/toonforce@.service
  ./usr/share/toonforce/scenes/wall.toml ./usr/share/toonforce/scenes/hands/strike.toml
  ./usr/share/toonforce/plot_trace.py ./usr/share/doc/toonforce/DEPLOY.md)
foreach(file IN LISTS files_toonforce)
  expect("toonforce ships no headers or libraries (${file})" NOT file MATCHES "^\\./usr/(include|lib/.*\\.a$)")
endforeach()
expect_field(toonforce "Package: toonforce\n")
expect_field(toonforce "libfmt")  # from dpkg-shlibdeps
file(READ "${WORK_DIR}/control/toonforce/conffiles" conffiles)
expect("the limits snippet is a conffile" conffiles STREQUAL "/etc/security/limits.d/toonforce.conf\n")
foreach(script IN ITEMS postinst prerm postrm)
  set(path "${WORK_DIR}/control/toonforce/${script}")
  expect("toonforce has a ${script}" EXISTS "${path}")
  run("sh -n ${script}" ignored sh -n "${path}")
  file(READ "${path}" text)
  foreach(forbidden IN ITEMS useradd adduser groupadd addgroup "systemctl enable" "systemctl start")
    string(FIND "${text}" "${forbidden}" at)
    expect("${script} does not run '${forbidden}'" at EQUAL -1)
  endforeach()
endforeach()
# The unit in the package is written for /usr and /etc.
run("dpkg-deb -x toonforce" ignored "${DPKG_DEB}" --extract "${deb_toonforce}" "${WORK_DIR}/root")
file(READ "${WORK_DIR}/root/usr/lib/systemd/system/toonforce@.service" unit)
foreach(line IN ITEMS "ExecStart=/usr/bin/toonforce run " "Environment=TOONFORCE_SCENE=/usr/share/toonforce/scenes/%i.toml"
                      "EnvironmentFile=-/etc/toonforce/%i.conf" "LimitRTPRIO=95" "LimitMEMLOCK=infinity")
  string(FIND "${unit}" "\n${line}" at)
  expect("'${line}' in the packaged unit" NOT at EQUAL -1)
endforeach()

# ---- toonforce-dev and the backends ------------------------------------------------------------
set(dev_files "${files_toonforce-dev}")
list(FILTER dev_files INCLUDE REGEX "/cmake/toonforce/toonforce-config\\.cmake$|/pkgconfig/toonforce\\.pc$|/libtoonforce_control\\.a$")
list(LENGTH dev_files n)
expect("toonforce-dev has the package config, toonforce.pc and the control library: ${dev_files}" n EQUAL 3)
expect_files(toonforce-dev ./usr/include/toonforce/control/servo_loop.hpp ./usr/include/toonforce/effects/scene.hpp
  ./usr/include/toonforce/hal/device.hpp ./usr/share/doc/toonforce/examples/compose_scene.cpp)
expect_field(toonforce-dev "libtomlplusplus-dev")
expect_files(toonforce-falcon-dev ./usr/include/toonforce/hal/falcon/falcon.hpp)
expect_files(toonforce-gpio-dev ./usr/include/toonforce/hal/gpio/gpio_session.hpp)
expect_files(toonforce-omni-dev ./usr/include/toonforce/hal/omni/omni_device.hpp)
expect_field(toonforce-omni-dev "libhidapi-dev")
foreach(backend IN ITEMS falcon gpio omni)
  expect_field(toonforce-${backend}-dev "toonforce-dev (= ${VERSION})")
  set(backend_files "${files_toonforce-${backend}-dev}")
  list(FILTER backend_files INCLUDE REGEX "/libtoonforce_hal_${backend}\\.a$|/toonforce-${backend}\\.pc$|/toonforce-${backend}\\.cmake$")
  list(LENGTH backend_files n)
  expect("toonforce-${backend}-dev has its library, .pc and package part: ${backend_files}" n EQUAL 3)
endforeach()

# ---- the licence in every package ---------------------------------------------------------------
# Debian policy 12.5: each package's copyright file at /usr/share/doc/PACKAGE/copyright, here
# machine-readable (DEP-5); the program's package also carries the licence and the notices of
# what it embeds.
foreach(package IN ITEMS toonforce toonforce-dev toonforce-falcon-dev toonforce-gpio-dev toonforce-omni-dev)
  expect_files(${package} ./usr/share/doc/${package}/copyright)
endforeach()
expect_files(toonforce ./usr/share/doc/toonforce/LICENSE ./usr/share/doc/toonforce/THIRD-PARTY-NOTICES.md)
file(READ "${WORK_DIR}/root/usr/share/doc/toonforce/copyright" copyright)
string(FIND "${copyright}" "Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/" at)
expect("the copyright file is machine-readable (DEP-5)" at EQUAL 0)

# ---- nothing of the lab (docs/ARCHITECTURE.md "The lab") in any package ------------------------
string(REPLACE ";" "\n" listing "${all_files}")
file(WRITE "${WORK_DIR}/all-files.txt" "${listing}\n")
execute_process(COMMAND "${PYTHON}" "${CHECK_FILES}" --listing "${WORK_DIR}/all-files.txt"
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
expect("no file of the lab in the packages:\n${out}${err}" rc EQUAL 0)

message(STATUS "debian_package: all checks passed")
