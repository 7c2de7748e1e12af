# SPDX-License-Identifier: Apache-2.0
# The Falcon backend's part of toonforce's CMake package: toonforce::hal_falcon, a static
# library that links libusb-1.0 and nettle through the imported targets pkg-config makes
# (the same names as in toonforce's build: PkgConfig::LIBUSB, PkgConfig::NETTLE).
find_package(PkgConfig QUIET)
if(PKG_CONFIG_FOUND)
  pkg_check_modules(LIBUSB QUIET IMPORTED_TARGET libusb-1.0)
  pkg_check_modules(NETTLE QUIET IMPORTED_TARGET nettle)
endif()
if(TARGET PkgConfig::LIBUSB AND TARGET PkgConfig::NETTLE)
  include("${CMAKE_CURRENT_LIST_DIR}/toonforce-falcon-targets.cmake")
  set(toonforce_falcon_FOUND TRUE)
else()
  set(toonforce_falcon_FOUND FALSE)
  set(toonforce_NOT_FOUND_MESSAGE
      "the toonforce falcon backend needs pkg-config, libusb-1.0 and nettle (Debian: pkg-config libusb-1.0-0-dev nettle-dev)")
endif()
