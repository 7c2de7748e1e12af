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

}  // namespace toonforce
