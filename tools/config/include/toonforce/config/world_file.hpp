// SPDX-License-Identifier: Apache-2.0
#pragma once
/// World scene files: a scene of several devices (docs/spec/interfaces.md "World scenes"). A
/// scene file is a world when it has `[[device]]` tables (an array of tables; a one-device scene
/// has the `[device]` table, or none). Besides the effects, read as in any scene file (they act
/// on every device, in the world frame), a world has:
///
///   [[device]]    one per device: `name` (required, unique: traces and messages use it),
///                 `backend` ("sim", "falcon", "omni"; default "sim"), `select` (which one: a
///                 serial, a bus path or an OpenHaptics device name; default: the only one),
///                 where it sits in the world (`offset` [m], `yaw` [deg] about z, `scale`), and
///                 every key of the one-device `[device]` table (its own limits and safety).
///   [[coupling]]  a spring-damper between two devices' HIPs: `between = ["a", "b"]` (device
///                 names), `stiffness` [N/m], `damping` [N s/m], `rest_length` [m].
///   [ball]        a ball every device can push: `radius` [m], `mass` [kg], `stiffness`,
///                 `damping`, `drag`, `start` [m]; optionally a wall it bounces off:
///                 `wall_point`, `wall_normal`, `wall_stiffness`, `wall_damping`; optionally
///                 the cartoon effects on its surface, with the single-device tables' keys:
///                 `[ball.slippery]` (`mu`, `max_tangential_force`) and `[ball.impact]`
///                 (`recoil_gain`, `oscillation_gain`, `duration`, `frequency`,
///                 `min_impact_speed`, `rearm_distance`, `sine`).
///   [world]       `stop = "all"` (default: one device's latched fault holds every device) or
///                 `"each"` (independent stations).
///
/// Every error names the file, the line and the key, and nothing runs while there is one.

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/world.hpp"
#include "toonforce/effects/between.hpp"

namespace toonforce {

/// The most devices a world file may list (the world is sized at compile time: control/world.hpp).
inline constexpr std::size_t kMaxWorldDevices = 4;

/// One `[[device]]` of a world file.
struct WorldDeviceEntry {
  std::string name;
  std::string backend = "sim";  ///< "sim", "falcon" or "omni"
  std::string select;           ///< which device of that backend; empty: the only one
  DeviceFrame frame;
  /// The device's own `[device]` keys (limits, safety), defaults filled in; `name` is the
  /// device's name and `source` the file.
  SceneSettings settings;
  std::uint32_t line = 0;
};

/// One `[[coupling]]`: device indices into WorldDescription::devices.
struct WorldCouplingEntry {
  std::size_t a = 0;
  std::size_t b = 1;
  between::CouplingParams params;
  std::uint32_t line = 0;
};

/// Every device (the bit mask of an effect that names none).
inline constexpr std::uint32_t kAllDevices = ~0U;

/// A world file, read and checked whole.
struct WorldDescription {
  SceneDescription scene;  ///< every effect and the file's name
  /// Per effect kind (BuiltinEffects order), per effect of that kind in file order: the devices
  /// it acts on (bit i: device i), from its `devices` key; kAllDevices without one.
  std::array<std::vector<std::uint32_t>, SceneDescription::kKinds> effect_devices;
  std::uint32_t ball_devices = kAllDevices;  ///< the devices that touch the ball ([ball] devices)
  std::vector<WorldDeviceEntry> devices;
  std::vector<WorldCouplingEntry> couplings;
  std::optional<between::BallParams> ball;  ///< normalised (check_and_normalise passed)
  StopPolicy stop = StopPolicy::kAll;

  /// The effects that act on device `device` (its scene), in file order.
  SceneDescription scene_for(std::size_t device) const;
  /// The index of the device called `name`, or devices.size().
  std::size_t device_index(std::string_view name) const noexcept;
};

/// Whether the TOML text (or file) has `[[device]]` tables: a world, not a one-device scene.
/// False for text that does not parse (the scene reader then says why).
bool is_world_text(std::string_view text);
bool is_world_file(const std::string& path);

/// Reads and checks a world file (double scalars only: a world runs on the host).
Result<WorldDescription> load_world_file(const std::string& path);
/// The same from text; `source_name` stands for the file in messages.
Result<WorldDescription> parse_world(std::string_view text, std::string_view source_name);

/// The world's configuration (couplings, ball, stop policy) for control/world.hpp.
WorldConfig world_config(const WorldDescription& world);

}  // namespace toonforce
