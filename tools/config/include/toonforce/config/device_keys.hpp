// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The `[device]` keys of a scene file, each declared once (device_keys.cpp) with its type,
/// unit, range, default and meaning. From that one table come the reader (read_device_keys:
/// the checks and the file:line:key errors) and the spec's table of the keys
/// (device_keys_markdown, between generated markers in docs/spec/interfaces.md; a test checks
/// that the spec's table is this one). Defaults are the configuration structs' own
/// (SceneSettings{}: ForceLimits, SafetyConfig), so they too are written once.

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "toonforce/config/toml_reader.hpp"

namespace toonforce {

struct SceneSettings;

/// How a key's value is written in the file.
enum class DeviceKeyType : std::uint8_t {
  kNumber,       ///< a number in `range`, below `below` if that is finite
  kWholeNumber,  ///< an integer >= `min_whole`
  kFlag,         ///< true or false
  kBox,          ///< `key` and `upper_key`, two [x, y, z]: both or neither, lower < upper on every axis
};

struct DeviceKey {
  std::string_view key = {};
  DeviceKeyType type = DeviceKeyType::kNumber;
  std::string_view unit = {};  ///< SI unit ("N", "m/s"); empty for a pure number
  Range range = Range::kAny;
  double below = 0.0;  ///< kNumber: an exclusive upper bound when `has_below`
  bool has_below = false;
  std::string_view below_why = {};     ///< the reason a range error gives for `below`
  std::int64_t min_whole = 0;          ///< kWholeNumber: the least value
  std::string_view upper_key = {};     ///< kBox: the upper corner's key
  std::string_view default_text = {};  ///< the default in words, when it is not a value
  std::string_view doc = {};           ///< what it does (effects.md §6 says more)
  // Where the value goes in the settings (one of them, by type). `present`, if set, is raised
  // when the file gives the key: the default is then "unset" (default_text says what holds).
  double* (*number)(SceneSettings&) = nullptr;
  bool* (*present)(SceneSettings&) = nullptr;
  std::int64_t* (*whole)(SceneSettings&) = nullptr;
  bool* (*flag)(SceneSettings&) = nullptr;
  Vec3<double>* (*lower)(SceneSettings&) = nullptr;
  Vec3<double>* (*upper)(SceneSettings&) = nullptr;
};

/// Every `[device]` key, in the order they are read.
std::span<const DeviceKey> device_keys() noexcept;

/// Reads every `[device]` key of `r` into `settings` (whose values are the defaults), recording
/// each problem in `r`'s errors with the key's line. Does not call r.finish().
void read_device_keys(TableReader& r, SceneSettings& settings);

/// The spec's table of the `[device]` keys (Markdown, one row a key), from device_keys().
std::string device_keys_markdown();

}  // namespace toonforce
