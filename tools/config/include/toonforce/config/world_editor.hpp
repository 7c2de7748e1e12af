// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Live scenes of a world, the application's side (docs/spec/live-scenes.md, "Worlds"): the
/// control protocol's changes to a running world (`run --scene WORLD --control`), from the
/// server's thread.
///
///   WorldMailbox<RuntimeScene<double>> mailbox;          // sized at start-up, outlives both
///   auto editor = WorldEditor::open(text, "scenes/two_players.toml", mailbox);
///   world.listen(mailbox);                               // a World built with kLiveStages
///   editor->set("surface1", "stiffness = 800");          // every device it acts on, one tick
///   editor->fire("surface1", "impact", 0.3);             // on each of those devices
///
/// A change edits the world file's text and reads it again with the world files' reader (its
/// rules, its messages: the key, the line in the change's text); then each device's scene (the
/// effects that act on it) goes into one update, so that every device takes it on the same
/// world tick. What a world keeps while it runs, and refuses to change: its devices, couplings,
/// ball and stop policy; which devices an effect acts on (`devices`); the list of effects (add,
/// remove, and load are refused: the trace and the viewer show each device's effects by
/// column). Not real-time code: it parses and allocates.

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "toonforce/common/result.hpp"
#include "toonforce/config/world_file.hpp"
#include "toonforce/control/world_updates.hpp"

namespace toonforce {

class WorldEditor {
 public:
  using Mailbox = WorldMailbox<RuntimeScene<double>>;
  using Update = WorldUpdate<RuntimeScene<double>>;

  /// `text` is the world the loop starts with; `source` names it in messages.
  static Result<WorldEditor> open(std::string_view text, std::string source, Mailbox& mailbox);
  WorldEditor(WorldEditor&&) noexcept;
  WorldEditor& operator=(WorldEditor&&) noexcept;
  ~WorldEditor();

  /// The keys given replace the effect's (`"surface2"`: the world file's second [[surface]]),
  /// on every device it acts on.
  Result<std::uint64_t> set(std::string_view effect, std::string_view keys_toml);
  /// One-shot event `event` of `effect`, fired on every device it acts on.
  Result<std::uint64_t> fire(std::string_view effect, std::string_view event, double value);
  /// Refused in a world, with the reason (the list of effects and the devices are fixed).
  Result<std::uint64_t> add(std::string_view kind);
  Result<std::uint64_t> remove(std::string_view effect);
  Result<std::uint64_t> load(std::string_view source);

  /// The world after the changes sent so far.
  const WorldDescription& world() const noexcept;
  /// The sequence of the last update the world applied (0: none yet).
  std::uint64_t applied() const noexcept;

 private:
  struct Impl;
  explicit WorldEditor(std::unique_ptr<Impl> impl) noexcept;
  std::unique_ptr<Impl> impl_;
};

}  // namespace toonforce
