// SPDX-License-Identifier: Apache-2.0
// dlopen/dlsym of the OpenHaptics HD library; every failure becomes a message saying what to
// install or fix. See hd_library.hpp for the search order and the never-unload rule.
#include "toonforce/hal/omni/hd_library.hpp"

#include <dlfcn.h>
#include <link.h>

#include <bit>
#include <cctype>
#include <climits>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <vector>

#include <fmt/format.h>

namespace toonforce::hd {
namespace {

// CHAI3D's flags (OMNI.md §2.1), proven with the real driver; RTLD_NODELETE makes a stray
// dlclose harmless too, since the library must never be unloaded.
constexpr int kOpenFlags = RTLD_LAZY | RTLD_GLOBAL | RTLD_NODELETE;

std::mutex g_mutex;
// Every library loaded, by resolved path; the Library objects are never freed (never unloaded).
std::map<std::string, const Library*>& loaded() {
  static auto* libraries = new std::map<std::string, const Library*>();
  return *libraries;
}

template <class F>
void bind(void* handle, const char* name, F& slot, std::vector<std::string>& missing) {
  void* symbol = dlsym(handle, name);
  if (symbol == nullptr) {
    missing.emplace_back(name);
    return;
  }
  static_assert(sizeof(F) == sizeof(void*));
  slot = std::bit_cast<F>(symbol);  // POSIX guarantees function and object pointers convert
}

std::vector<std::string> bind_all(void* handle, HdFunctions& f) {
  std::vector<std::string> missing;
  bind(handle, "hdInitDevice", f.hdInitDevice, missing);
  bind(handle, "hdDisableDevice", f.hdDisableDevice, missing);
  bind(handle, "hdMakeCurrentDevice", f.hdMakeCurrentDevice, missing);
  bind(handle, "hdBeginFrame", f.hdBeginFrame, missing);
  bind(handle, "hdEndFrame", f.hdEndFrame, missing);
  bind(handle, "hdGetError", f.hdGetError, missing);
  bind(handle, "hdGetErrorString", f.hdGetErrorString, missing);
  bind(handle, "hdEnable", f.hdEnable, missing);
  bind(handle, "hdDisable", f.hdDisable, missing);
  bind(handle, "hdIsEnabled", f.hdIsEnabled, missing);
  bind(handle, "hdGetBooleanv", f.hdGetBooleanv, missing);
  bind(handle, "hdGetIntegerv", f.hdGetIntegerv, missing);
  bind(handle, "hdGetDoublev", f.hdGetDoublev, missing);
  bind(handle, "hdGetString", f.hdGetString, missing);
  bind(handle, "hdSetDoublev", f.hdSetDoublev, missing);
  bind(handle, "hdCheckCalibration", f.hdCheckCalibration, missing);
  bind(handle, "hdUpdateCalibration", f.hdUpdateCalibration, missing);
  bind(handle, "hdStartScheduler", f.hdStartScheduler, missing);
  bind(handle, "hdStopScheduler", f.hdStopScheduler, missing);
  bind(handle, "hdSetSchedulerRate", f.hdSetSchedulerRate, missing);
  bind(handle, "hdScheduleAsynchronous", f.hdScheduleAsynchronous, missing);
  bind(handle, "hdUnschedule", f.hdUnschedule, missing);
  bind(handle, "hdGetSchedulerTimeStamp", f.hdGetSchedulerTimeStamp, missing);
  return missing;
}

/// The file dlopen actually mapped (the loader's search result), symbolic links resolved.
std::string loaded_path(void* handle, std::string_view fallback) {
  link_map* map = nullptr;
  std::string path(fallback);
  if (dlinfo(handle, RTLD_DI_LINKMAP, &map) == 0 && map != nullptr && map->l_name != nullptr &&
      map->l_name[0] != '\0') {
    path = map->l_name;
  }
  std::error_code ec;
  const auto canonical = std::filesystem::canonical(path, ec);
  return ec ? path : canonical.string();
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i > 0) out += i + 1 == items.size() ? " and " : ", ";
    out += items[i];
  }
  return out;
}

constexpr std::string_view kInstallAdvice =
    "Install OpenHaptics 3.4 for Linux and the 3D Systems Touch Device Driver from 3D Systems "
    "(toonforce cannot ship them: their licence forbids redistribution). OpenHaptics 3.0 and the "
    "PHANTOM Device Drivers install into /usr/lib64, which Debian and Ubuntu do not search: "
    "`echo /usr/lib64 | sudo tee /etc/ld.so.conf.d/openhaptics.conf && sudo ldconfig` "
    "(`sudo ldconfig` alone does not add it; `toonforce devices` checks)";

struct Attempt {
  void* handle = nullptr;
  LoadProblem problem = LoadProblem::kNone;
  std::string detail;      // dlerror() text
  std::string dependency;  // the missing library, for kDependencyMissing
};

/// dlopen one candidate and tell "not there" from "there but a dependency is missing".
Attempt try_open(const std::string& candidate) {
  Attempt a;
  dlerror();
  a.handle = dlopen(candidate.c_str(), kOpenFlags);
  if (a.handle != nullptr) return a;
  const char* error = dlerror();
  a.detail = error != nullptr ? error : "unknown dlopen error";
  // glibc: "<object>: cannot open shared object file: No such file or directory", where
  // <object> is the file that could not be opened: the candidate itself, or a dependency.
  constexpr std::string_view kCannotOpen = ": cannot open shared object file";
  const auto at = a.detail.find(kCannotOpen);
  if (at != std::string::npos) {
    const std::string object = a.detail.substr(0, at);
    if (object == candidate) {
      a.problem = LoadProblem::kNotFound;
    } else {
      a.problem = LoadProblem::kDependencyMissing;
      a.dependency = object;
    }
  } else {
    a.problem = LoadProblem::kNotLoadable;
  }
  return a;
}

LoadOutcome fail(LoadProblem problem, std::string what, std::string fix) {
  const auto upper = [](char c) { return static_cast<char>(std::toupper(static_cast<unsigned char>(c))); };
  std::string message = what + ". " + fix + ".";
  message[0] = upper(message[0]);
  message[what.size() + 2] = upper(message[what.size() + 2]);
  return LoadOutcome{nullptr, problem, std::move(message), std::move(what), std::move(fix)};
}

}  // namespace

int major_version(std::string_view version) noexcept {
  int value = 0;
  std::size_t digits = 0;
  for (const char c : version) {
    if (c < '0' || c > '9') break;
    if (value > INT_MAX / 10 - 10) return -1;
    value = value * 10 + (c - '0');
    ++digits;
  }
  return digits == 0 ? -1 : value;
}

std::string version_from_file_name(std::string_view file_name) {
  constexpr std::string_view kStem = ".so.";
  const auto at = file_name.rfind(kStem);
  if (at == std::string_view::npos) return {};
  const std::string_view rest = file_name.substr(at + kStem.size());
  if (rest.empty() || rest.front() < '0' || rest.front() > '9') return {};
  return std::string(rest);
}

std::string dependency_fix(std::string_view name) {
  constexpr std::string_view kLib64 =
      "; if it is installed in /usr/lib64, which Debian and Ubuntu do not search: `echo /usr/lib64 | "
      "sudo tee /etc/ld.so.conf.d/openhaptics.conf && sudo ldconfig`";
  if (name.starts_with("libPhantomIOLib")) {
    return fmt::format("install the 3D Systems Touch Device Driver (TouchDriver_*), which provides it, then "
                       "run `sudo ldconfig`{}",
                       kLib64);
  }
  if (name.starts_with("libPHANToMIO")) {
    return fmt::format("install the PHANTOM Device Drivers (PDD 4.3) for the FireWire Omni, which provide "
                       "it, then run `sudo ldconfig`{}",
                       kLib64);
  }
  if (name.starts_with("libraw1394.so.8")) {
    // The FireWire driver was built against libraw1394's older soname (OMNI.md §5).
    return "the FireWire Omni's driver wants libraw1394.so.8; Debian ships libraw1394.so.11: `sudo apt-get "
           "install libraw1394-11 && sudo ln -s /usr/lib/x86_64-linux-gnu/libraw1394.so.11 "
           "/usr/lib/x86_64-linux-gnu/libraw1394.so.8 && sudo ldconfig`";
  }
  if (name.starts_with("libncurses.so.5") || name.starts_with("libtinfo.so.5")) {
    return "install the ncurses 5 compatibility libraries: `sudo apt-get install libncurses5 "
           "libtinfo5`";
  }
  if (name.starts_with("libraw1394")) return "install libraw1394: `sudo apt-get install libraw1394-11`";
  return fmt::format("install the package that provides {} (`apt-file search {}` finds it)", name, name);
}

LoadOutcome load_library(std::string_view path) {
  std::lock_guard lock(g_mutex);

  // Which files to try, and how to name where the choice came from in messages.
  std::vector<std::string> candidates;
  std::string origin;
  if (!path.empty()) {
    candidates.emplace_back(path);
    origin = fmt::format("the OpenHaptics library path {}", path);
  } else if (const char* env = std::getenv(kLibraryEnvVar); env != nullptr && env[0] != '\0') {
    candidates.emplace_back(env);
    origin = fmt::format("{}={}", kLibraryEnvVar, env);
  } else {
    for (const char* name : kDefaultLibraryNames) candidates.emplace_back(name);
  }
  const bool searched = origin.empty();

  Attempt found;
  std::string opened;
  for (const std::string& candidate : candidates) {
    Attempt a = try_open(candidate);
    // Loaded, or there but unusable: either is the answer (rather than trying on).
    if (a.handle != nullptr || a.problem != LoadProblem::kNotFound) {
      found = std::move(a);
      opened = candidate;
      break;
    }
    found = std::move(a);
  }

  if (found.handle == nullptr) {
    switch (found.problem) {
      case LoadProblem::kDependencyMissing:
        return fail(LoadProblem::kDependencyMissing,
                    fmt::format("{} was found but needs {}, which the dynamic loader cannot find "
                                "(dlopen said: {})",
                                opened, found.dependency, found.detail),
                    dependency_fix(found.dependency));
      case LoadProblem::kNotLoadable:
        return fail(LoadProblem::kNotLoadable, fmt::format("{} could not be loaded: {}", opened, found.detail),
                    "it must be OpenHaptics' libHD.so for this machine (64-bit x86-64 Linux)");
      default: break;
    }
    if (searched) {
      return fail(LoadProblem::kNotFound,
                  "OpenHaptics is not installed, or not where the dynamic loader looks: none of "
                  "libHD.so, libHD.so.3.4, libHD.so.3.0 was found",
                  fmt::format("{}. If libHD.so is installed elsewhere, set {}=/path/to/libHD.so", kInstallAdvice,
                              kLibraryEnvVar));
    }
    return fail(LoadProblem::kNotFound, fmt::format("{} does not exist or cannot be read", origin),
                "point it at OpenHaptics' libHD.so (the installer puts it in /usr/lib), or leave it "
                "unset to search libHD.so, libHD.so.3.4 and libHD.so.3.0");
  }

  const std::string resolved = loaded_path(found.handle, opened);
  if (auto it = loaded().find(resolved); it != loaded().end()) return LoadOutcome{it->second, {}, {}, {}, {}};

  // Version in the file name (libHD.so.3.4.0): refuse another major version before use.
  const std::string file_version = version_from_file_name(std::filesystem::path(resolved).filename().string());
  if (!file_version.empty() && major_version(file_version) != kSupportedMajorVersion) {
    return fail(LoadProblem::kWrongVersion,
                fmt::format("{} is OpenHaptics HD library version {}, but toonforce needs version {} "
                            "(3.4 for the Touch, 3.0 for the FireWire Omni)",
                            resolved, file_version, kSupportedMajorVersion),
                fmt::format("{}, or set {} to its libHD.so", kInstallAdvice, kLibraryEnvVar));
  }

  HdFunctions functions;
  const std::vector<std::string> missing = bind_all(found.handle, functions);
  if (!missing.empty()) {
    return fail(LoadProblem::kSymbolMissing,
                fmt::format("{} is not a usable OpenHaptics HD library: it does not export {} ({} of "
                            "the {} HD functions toonforce uses)",
                            resolved, join(missing), missing.size(), kFunctionCount),
                fmt::format("Install OpenHaptics 3.0 or later, or point {} at its libHD.so", kLibraryEnvVar));
  }

  const auto* library = new Library(found.handle, resolved, file_version, functions);
  loaded().emplace(resolved, library);
  return LoadOutcome{library, {}, {}, {}, {}};
}

}  // namespace toonforce::hd
