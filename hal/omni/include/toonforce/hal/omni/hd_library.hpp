// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Loads the OpenHaptics HD library at run time with dlopen and resolves the functions of
/// hd_api.hpp with dlsym (as CHAI3D and pyOpenHaptics do, OMNI.md §2.1): nothing of OpenHaptics
/// is needed to build toonforce, and a user without it gets a message saying what to install.
///
/// Search order: an explicit path (an option), else the file named by $TOONFORCE_LIBHD (for a
/// non-standard install, and how the tests load the fake library), else the dynamic loader's
/// search for libHD.so, libHD.so.3.4, libHD.so.3.0. A library is never unloaded: CHAI3D found
/// that the driver fails when it is loaded and closed twice (OMNI.md §2.1), so a loaded
/// library stays for the life of the process and loading the same file again returns it.
/// Start-up code: allocates, takes a lock; never call it from a tick.

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>

#include "toonforce/hal/omni/hd_api.hpp"

namespace toonforce::hd {

/// The environment variable naming the libHD file to load.
inline constexpr const char* kLibraryEnvVar = "TOONFORCE_LIBHD";
/// What the dynamic loader is asked for when no file is named, in this order.
inline constexpr const char* kDefaultLibraryNames[] = {"libHD.so", "libHD.so.3.4", "libHD.so.3.0"};
/// OpenHaptics 3.x: 3.0 (AE, FireWire Omni) and 3.4 (Touch) share the API we use.
inline constexpr int kSupportedMajorVersion = 3;
/// How many HD functions toonforce resolves (all are required).
inline constexpr int kFunctionCount = static_cast<int>(sizeof(HdFunctions) / sizeof(void (*)()));

enum class LoadProblem : std::uint8_t {
  kNone,
  kNotFound,           ///< no such file / the loader found none of the default names
  kDependencyMissing,  ///< the file is there but a library it needs is not
  kNotLoadable,        ///< dlopen failed otherwise (not an ELF, wrong architecture, ...)
  kSymbolMissing,      ///< loaded, but a function we need is not exported
  kWrongVersion,       ///< loaded, but it is not OpenHaptics 3.x
};

/// A loaded HD library; lives until the process ends.
class Library {
 public:
  Library(void* handle, std::string path, std::string file_version, const HdFunctions& functions)
      : handle_(handle), path_(std::move(path)), file_version_(std::move(file_version)), functions_(functions) {}
  Library(const Library&) = delete;
  Library& operator=(const Library&) = delete;

  const HdFunctions& functions() const noexcept { return functions_; }
  /// The file loaded, symbolic links resolved.
  const std::string& path() const noexcept { return path_; }
  /// The version in the file's name ("3.4.0" for libHD.so.3.4.0); empty when it has none.
  const std::string& file_version() const noexcept { return file_version_; }
  void* handle() const noexcept { return handle_; }

 private:
  void* handle_;
  std::string path_;
  std::string file_version_;
  HdFunctions functions_;
};

struct LoadOutcome {
  const Library* library = nullptr;  ///< set on success
  LoadProblem problem = LoadProblem::kNone;
  std::string message;  ///< what went wrong and what to do: "<what>. <Fix>."; empty on success
  std::string what;     ///< what went wrong, alone
  std::string fix;      ///< what to install or change, alone
};

/// Loads the HD library (see the search order above); `path` empty means "no explicit path".
LoadOutcome load_library(std::string_view path = {});

/// The leading major number of a version text ("3.40.1" -> 3, "v2" -> -1), or -1.
int major_version(std::string_view version) noexcept;
/// "libHD.so.3.4.0" -> "3.4.0"; "" when the name carries no version.
std::string version_from_file_name(std::string_view file_name);
/// The fix for a missing dependency of libHD ("install the Touch Device Driver ...").
std::string dependency_fix(std::string_view library_name);

}  // namespace toonforce::hd
