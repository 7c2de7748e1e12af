// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Where an installed toonforce keeps its data (cmake/ToonforceInstall.cmake): scenes, hand
/// scripts and motions under <prefix>/share/toonforce/scenes, the plotting script beside them.
/// Found from the running binary's own place (/proc/self/exe), so a tree installed to any
/// prefix, or unpacked from the Debian package, finds its own files. Start-up code only.

#include <string>

namespace toonforce {

/// <directory of this executable>/<bindir-to-datadir>, e.g. /usr/bin/../share/toonforce, if
/// that directory exists; empty otherwise (a binary run from its build tree).
std::string installed_data_dir();

/// The source tree this binary was built from: a build tree's binary's fallback for its scenes
/// and plot script when no installed data is found beside it. One string, ended where the path
/// ends (an installed product's files are checked for any other copy of the build machine's
/// path: tests/install/check_install_files.py).
const char* build_source_dir() noexcept;

}  // namespace toonforce
