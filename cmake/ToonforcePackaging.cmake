# SPDX-License-Identifier: Apache-2.0
# Debian packages with CPack, one per install component (cmake/ToonforceInstall.cmake):
#   cpack --config build/<preset>/CPackConfig.cmake -G DEB      (or: cd build/<preset> && cpack -G DEB)
# gives toonforce_<v>_<arch>.deb (the program, scenes, udev rule, limits snippet, unit
# template), toonforce-dev (headers, core libraries, CMake and pkg-config files) and one -dev
# package per device backend. CPack installs with prefix /usr under a staging DESTDIR, so any
# build tree makes a correct package (tests/install/deb_test.cmake checks one in every workflow).
#
# Maintainer scripts (cmake/package/debian/): only what installing a udev rule and a unit needs:
# postinst asks a running udev to apply the rule to a Falcon plugged in now and a running
# systemd to see the unit template; prerm stops running toonforce@ instances before removal
# (force zero first); postrm reloads udev and systemd after it. Nothing enables or starts the
# service, and nothing creates users or groups: the unit runs as a DynamicUser with
# group plugdev (Debian's), and the limits snippet names a group "realtime" the administrator
# creates if people log in to run toonforce (docs/DEPLOY.md).
set(TOONFORCE_PACKAGE_CONTACT "toonforce maintainers <toonforce@localhost>" CACHE STRING
    "Maintainer field of the Debian packages")

set(CPACK_PACKAGE_NAME toonforce)
set(CPACK_PACKAGE_VENDOR "toonforce")
set(CPACK_PACKAGE_CONTACT "${TOONFORCE_PACKAGE_CONTACT}")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "expressive (cartoon-inspired) haptic rendering on real haptic devices")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_GENERATOR DEB)
set(CPACK_SOURCE_GENERATOR "")

set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL runtime devel)
foreach(backend IN LISTS TOONFORCE_BACKEND_COMPONENTS)
  list(APPEND CPACK_COMPONENTS_ALL ${backend}_devel)
endforeach()
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # name_version_arch.deb
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)

# The program: its shared-library dependencies from dpkg-shlibdeps (package dpkg-dev).
set(CPACK_DEBIAN_RUNTIME_PACKAGE_NAME toonforce)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_RECOMMENDS "python3-matplotlib")  # plots: toonforce sim --plot, figures
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SUGGESTS "rt-tests, linux-image-rt-amd64, linux-cpupower")  # docs/DEPLOY.md
string(CONCAT CPACK_COMPONENT_RUNTIME_DESCRIPTION
    "real-time haptic controller rendering cartoon effects on haptic devices\n"
    "The toonforce program renders the cartoon effects of \"Expressive Haptic Rendering with\n"
    "Cartoon-Inspired Effects\" (super-slippery surface, impact recoil, cartoon cliff) beside\n"
    "realistic baselines on a Novint Falcon, a Phantom Omni / Touch or a host simulation, with\n"
    "the bundled scenes, the Falcon's udev rule, a limits.d snippet for real-time scheduling and\n"
    "a systemd unit template (toonforce@.service, not enabled) for a dedicated host.")
foreach(script postinst prerm postrm)
  configure_file(${PROJECT_SOURCE_DIR}/cmake/package/debian/${script}
                 ${PROJECT_BINARY_DIR}/package/debian/${script} COPYONLY)
endforeach()
# /etc/security/limits.d/toonforce.conf is the administrator's to edit: a conffile, which dpkg
# keeps on upgrade and removal (until purge).
file(WRITE ${PROJECT_BINARY_DIR}/package/debian/conffiles "/etc/security/limits.d/toonforce.conf\n")
set(CPACK_DEBIAN_RUNTIME_PACKAGE_CONTROL_EXTRA
    ${PROJECT_BINARY_DIR}/package/debian/postinst
    ${PROJECT_BINARY_DIR}/package/debian/prerm
    ${PROJECT_BINARY_DIR}/package/debian/postrm
    ${PROJECT_BINARY_DIR}/package/debian/conffiles)

set(CPACK_DEBIAN_DEVEL_PACKAGE_NAME toonforce-dev)
set(CPACK_DEBIAN_DEVEL_PACKAGE_DEPENDS "libfmt-dev, libtomlplusplus-dev")
set(CPACK_DEBIAN_DEVEL_PACKAGE_SUGGESTS "cmake, pkg-config, g++ (>= 4:12)")
string(CONCAT CPACK_COMPONENT_DEVEL_DESCRIPTION
    "toonforce libraries and headers, for embedding its effects and servo loop\n"
    "Static C++20 libraries with their headers: the force laws and compile-time scenes\n"
    "(toonforce::effects), the device seam (toonforce::hal), the controller, safety layer and\n"
    "servo loop (toonforce::control, toonforce::control_rt), the host simulation\n"
    "(toonforce::host_sim), scene files (toonforce::config) and traces (toonforce::trace); a CMake\n"
    "package (find_package(toonforce)), pkg-config file toonforce.pc, and examples.")

set(_toonforce_backend_depends_falcon "libusb-1.0-0-dev, nettle-dev")
set(_toonforce_backend_depends_gpio "libgpiod-dev")
set(_toonforce_backend_depends_omni "libusb-1.0-0-dev, libhidapi-dev")
foreach(backend IN LISTS TOONFORCE_BACKEND_COMPONENTS)
  string(TOUPPER "${backend}_devel" component)
  set(CPACK_DEBIAN_${component}_PACKAGE_NAME toonforce-${backend}-dev)
  set(CPACK_DEBIAN_${component}_PACKAGE_DEPENDS
      "toonforce-dev (= ${PROJECT_VERSION}), ${_toonforce_backend_depends_${backend}}")
  string(CONCAT CPACK_COMPONENT_${component}_DESCRIPTION
      "toonforce ${backend} device backend, for embedding\n"
      "The static library toonforce::hal_${backend} with its headers, for find_package(toonforce\n"
      "COMPONENTS ${backend}) and pkg-config toonforce-${backend}.")
endforeach()

# The Python module (TOONFORCE_PYTHON): python3-toonforce, into Debian's python3
# (tools/python/CMakeLists.txt installs it under lib/python3/dist-packages).
if(TOONFORCE_PYTHON)
  list(APPEND CPACK_COMPONENTS_ALL python)
  set(CPACK_DEBIAN_PYTHON_PACKAGE_NAME python3-toonforce)
  set(CPACK_DEBIAN_PYTHON_PACKAGE_SECTION python)
  set(CPACK_DEBIAN_PYTHON_PACKAGE_SHLIBDEPS ON)
  # The module's ABI is that of the python3 it was built for (e.g. 3.11: >= 3.11, << 3.12).
  math(EXPR _toonforce_python_next_minor "${Python_VERSION_MINOR} + 1")
  set(CPACK_DEBIAN_PYTHON_PACKAGE_DEPENDS
      "python3 (>= ${Python_VERSION_MAJOR}.${Python_VERSION_MINOR}), python3 (<< ${Python_VERSION_MAJOR}.${_toonforce_python_next_minor}), python3-numpy")
  # toonforce.study (docs/STUDIES.md): its fits and tests need scipy, its report's plots matplotlib.
  set(CPACK_DEBIAN_PYTHON_PACKAGE_RECOMMENDS "python3-scipy, python3-matplotlib")
  string(CONCAT CPACK_COMPONENT_PYTHON_DESCRIPTION
      "toonforce from Python: import toonforce\n"
      "The toonforce controller's scene loader and checks, closed-loop simulation, replay and the\n"
      "paper's figures from Python 3, through the same C++ code as the toonforce program, with\n"
      "traces as numpy arrays.")
endif()

include(CPack)
