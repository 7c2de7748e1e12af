// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Live scenes, the application's side (docs/spec/live-scenes.md): changes to the
/// scene of a running servo loop, from the application's thread.
///
///   SceneMailbox<RuntimeScene<double>> mailbox;           // sized at start-up, outlives both
///   auto editor = SceneEditor<double>::open(text, "scenes/wall.toml", mailbox);
///   loop.listen(mailbox);                                 // a ServoLoop built with kLiveStages
///   editor->set("surface1", "stiffness = 800\npoint = [0, 0, 0.01]");   // retune, move
///   editor->add("surface", "point = [0, 0, -0.02]\nnormal = [0, 0, 1]\nstiffness = 500");
///   editor->remove("cliff1");
///   editor->fire("surface1", "impact", 0.3);              // a shake on demand, v_i = 0.3 m/s
///   editor->load(other_text, "scenes/ice.toml");          // switch scenes
///
/// Each change is checked with the rules and messages of scene files (the same reader: a typo
/// in a key is named with its line in the change's text and the key it was closest to); a change
/// that fails is refused whole with that message and nothing reaches the loop. A change that
/// passes is pushed whole into the mailbox; the loop applies it at the start of a tick (never
/// half of it). A full mailbox refuses the change too (the loop applies one a tick): the caller
/// may try again at its next frame. Not real-time code: it parses and allocates.
///
/// A change may not touch the [device] table: the safety limits are the loop's, fixed when it
/// starts.

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include "toonforce/common/result.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/control/scene_updates.hpp"

namespace toonforce {

/// A checked change of the scene, before it becomes an update for a scalar type.
struct SceneChange {
  SceneDescription scene;               ///< the whole scene after the change
  std::vector<std::int16_t> continues;  ///< per effect of `scene.order` (SceneUpdate::continues)
  struct Event {
    std::size_t effect = 0;  ///< place in scene.order
    std::string name;
    double value = 0.0;
  };
  std::vector<Event> events;
  std::string what;                ///< "set surface1", for messages
  std::shared_ptr<void> document;  ///< the edited TOML document, for SceneDocument::commit
};

/// The scene as a TOML document the changes edit (no scalar type, no mailbox): the part of the
/// editor that parses and checks.
class SceneDocument {
 public:
  static Result<SceneDocument> parse(std::string_view text, std::string source,
                                     ScalarKind scalar = ScalarKind::kDouble);
  SceneDocument(SceneDocument&&) noexcept;
  SceneDocument& operator=(SceneDocument&&) noexcept;
  ~SceneDocument();

  /// The keys in `keys_toml` replace the effect's (`"surface2"`: the second [[surface]]); its
  /// other keys stay. A sub-table given (impact) is merged key by key the same way.
  Result<SceneChange> set(std::string_view effect, std::string_view keys_toml) const;
  /// A new effect of kind `key` ("surface", "cliff") after the others, from its keys.
  Result<SceneChange> add(std::string_view key, std::string_view keys_toml) const;
  Result<SceneChange> remove(std::string_view effect) const;
  /// Another scene, whole: every state starts fresh.
  Result<SceneChange> load(std::string_view text, std::string source) const;
  /// One-shot event `event` of `effect` with `value` (the scene does not change).
  Result<SceneChange> fire(std::string_view effect, std::string_view event, double value) const;
  /// After the change was handed to the loop: it is the document from now on.
  void commit(const SceneChange& change);

  const SceneDescription& scene() const noexcept;
  std::uint64_t changes() const noexcept { return changes_; }

 private:
  struct Impl;
  explicit SceneDocument(std::unique_ptr<Impl> impl) noexcept;
  std::unique_ptr<Impl> impl_;
  std::uint64_t changes_ = 0;
};

/// The editor of a live scene in scalar S: checks each change (SceneDocument), turns it into a
/// SceneUpdate and pushes it to the loop's mailbox. Returns the update's sequence number (the
/// mailbox's applied() reaches it when the loop has applied it).
template <Scalar S>
class SceneEditor {
 public:
  using Runtime = RuntimeScene<S>;
  using Mailbox = SceneMailbox<Runtime>;
  using Update = SceneUpdate<Runtime>;

  /// `text` is the scene the loop starts with (make_runtime_scene<S>(editor.scene()) is it).
  static Result<SceneEditor> open(std::string_view text, std::string source, Mailbox& mailbox) {
    auto doc = SceneDocument::parse(text, std::move(source), scalar_kind_of<S>());
    if (!doc) return Error{doc.error()};
    return SceneEditor(std::move(doc.value()), mailbox);
  }

  Result<std::uint64_t> set(std::string_view effect, std::string_view keys_toml) {
    return send(doc_.set(effect, keys_toml));
  }
  Result<std::uint64_t> add(std::string_view key, std::string_view keys_toml) { return send(doc_.add(key, keys_toml)); }
  Result<std::uint64_t> remove(std::string_view effect) { return send(doc_.remove(effect)); }
  Result<std::uint64_t> load(std::string_view text, std::string source) {
    return send(doc_.load(text, std::move(source)));
  }
  Result<std::uint64_t> fire(std::string_view effect, std::string_view event, double value) {
    return send(doc_.fire(effect, event, value));
  }

  const SceneDescription& scene() const noexcept { return doc_.scene(); }
  /// From now on, refuse a change that alters the list of effects (their kinds, in order): a
  /// trace's and a viewer's columns are the starting scene's effects. `why` ends the message.
  void keep_layout(std::string why) { keep_layout_ = std::move(why); }
  /// The sequence of the last update the loop applied (0: none yet).
  std::uint64_t applied() const noexcept { return mailbox_->applied(); }

 private:
  SceneEditor(SceneDocument doc, Mailbox& mailbox) : doc_(std::move(doc)), mailbox_(&mailbox) {}

  Result<std::uint64_t> send(Result<SceneChange> change) {
    if (!change) return Error{change.error()};
    if (!keep_layout_.empty() && !same_layout(change->scene.order, doc_.scene().order)) {
      return Error{fmt::format("{}: refused: it changes the list of effects, and {}\n", change->what, keep_layout_)};
    }
    // Built here, once, off the loop's thread; the mailbox copies it in.
    auto update = std::make_unique<Update>();
    update->scene = make_runtime_scene<S>(change->scene);
    for (std::size_t i = 0; i < change->continues.size() && i < update->continues.size(); ++i) {
      update->continues[i] = change->continues[i];
    }
    for (const SceneChange::Event& e : change->events) {
      const int number = update->scene.event_index(e.effect, e.name);
      if (number < 0 || update->event_count == update->events.size()) {
        return Error{fmt::format("{}: no event '{}' here\n", change->what, e.name)};
      }
      update->events[update->event_count++] =
          SceneEvent{static_cast<std::uint16_t>(e.effect), static_cast<std::uint8_t>(number), e.value};
    }
    update->sequence = doc_.changes() + 1;
    if (!mailbox_->push(*update)) {
      return Error{fmt::format("{}: not applied: the loop has not yet taken the {} change(s) before it (it takes one a "
                               "tick); try again\n",
                               change->what, mailbox_->capacity())};
    }
    doc_.commit(change.value());
    return update->sequence;
  }

  static bool same_layout(const std::vector<SceneEntry>& a, const std::vector<SceneEntry>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (a[i].kind != b[i].kind || a[i].index != b[i].index) return false;
    }
    return true;
  }

  SceneDocument doc_;
  Mailbox* mailbox_;
  std::string keep_layout_;
};

}  // namespace toonforce
