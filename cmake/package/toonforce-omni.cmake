# SPDX-License-Identifier: Apache-2.0
# The Omni backend's part of toonforce's CMake package: toonforce::hal_omni, a static library
# that links libusb-1.0 and hidapi-hidraw through the imported targets pkg-config makes (the
# names in toonforce's build: PkgConfig::TOONFORCE_LIBUSB, PkgConfig::TOONFORCE_HIDAPI), and
# libdl (OpenHaptics is loaded at run time; nothing of it is needed to build).
find_package(PkgConfig QUIET)
if(PKG_CONFIG_FOUND)
  pkg_check_modules(TOONFORCE_LIBUSB QUIET IMPORTED_TARGET libusb-1.0)
  pkg_check_modules(TOONFORCE_HIDAPI QUIET IMPORTED_TARGET hidapi-hidraw)
endif()
if(TARGET PkgConfig::TOONFORCE_LIBUSB AND TARGET PkgConfig::TOONFORCE_HIDAPI)
  include("${CMAKE_CURRENT_LIST_DIR}/toonforce-omni-targets.cmake")
  set(toonforce_omni_FOUND TRUE)
else()
  set(toonforce_omni_FOUND FALSE)
  set(toonforce_NOT_FOUND_MESSAGE
      "the toonforce omni backend needs pkg-config, libusb-1.0 and hidapi-hidraw (Debian: pkg-config libusb-1.0-0-dev libhidapi-dev)")
endif()
