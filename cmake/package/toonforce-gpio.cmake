# SPDX-License-Identifier: Apache-2.0
# The GPIO backend's part of toonforce's CMake package: toonforce::hal_gpio, a static library
# that links libgpiod (1.6) through the imported target pkg-config makes (PkgConfig::LIBGPIOD,
# the name in toonforce's build).
find_package(PkgConfig QUIET)
if(PKG_CONFIG_FOUND)
  pkg_check_modules(LIBGPIOD QUIET IMPORTED_TARGET libgpiod>=1.6)
endif()
if(TARGET PkgConfig::LIBGPIOD)
  include("${CMAKE_CURRENT_LIST_DIR}/toonforce-gpio-targets.cmake")
  set(toonforce_gpio_FOUND TRUE)
else()
  set(toonforce_gpio_FOUND FALSE)
  set(toonforce_NOT_FOUND_MESSAGE
      "the toonforce gpio backend needs pkg-config and libgpiod >= 1.6 (Debian: pkg-config libgpiod-dev)")
endif()
