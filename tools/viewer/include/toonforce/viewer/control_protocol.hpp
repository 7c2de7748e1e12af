// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The control protocol of live scenes (docs/spec/control-protocol.md): JSON text
/// messages on a WebSocket at /control of the viewer's server, from a game engine, a browser
/// page or a script, that change the scene of the running loop through its SceneEditor.
///
/// This file is the protocol without the socket: one `ControlSession` per connection turns a
/// message into a change (or refuses it) and into the reply to send. The server calls it from
/// its one thread, which is therefore the editor's only producer (the mailbox is single-producer).
/// Authentication (the first message must carry the token), rate limits and size limits are
/// here; the server's Host and Origin checks come before.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "toonforce/common/result.hpp"
#include "toonforce/config/scene_editor.hpp"

namespace toonforce::viewer {

inline constexpr int kControlProtocolVersion = 1;

/// Bounds of a message (docs/spec/control-protocol.md, Limits), checked before it is parsed.
/// Arrays and objects nest at most this deep (the message itself is level 1): a linear scan of
/// the text outside strings counts it, so no parse or recursion ever meets a deeper message.
inline constexpr std::size_t kControlMaxDepth = 32;
/// An "id" is a number, a string of at most this many bytes, true, false or null; else refused.
inline constexpr std::size_t kControlMaxIdBytes = 128;
/// A name a reply quotes from the message it refuses (a type, a field, a key) is cut to this
/// many bytes; an error's whole message to kControlMaxErrorBytes.
inline constexpr std::size_t kControlMaxEchoBytes = 64;
inline constexpr std::size_t kControlMaxErrorBytes = 1024;

/// What the protocol drives: a live scene's editor, whatever its scalar type.
class SceneControl {
 public:
  virtual ~SceneControl() = default;
  virtual Result<std::uint64_t> set(std::string_view effect, std::string_view keys_toml) = 0;
  virtual Result<std::uint64_t> add(std::string_view kind, std::string_view keys_toml) = 0;
  virtual Result<std::uint64_t> remove(std::string_view effect) = 0;
  virtual Result<std::uint64_t> load(std::string_view text, std::string name) = 0;
  virtual Result<std::uint64_t> fire(std::string_view effect, std::string_view event, double value) = 0;
  /// The sequence of the last update the loop applied.
  virtual std::uint64_t applied() const = 0;
  /// The scene as it is after the changes sent so far (the viewer's scene JSON).
  virtual std::string scene_json() const = 0;
};

/// SceneControl over a SceneEditor<S>.
template <Scalar S>
class EditorControl final : public SceneControl {
 public:
  explicit EditorControl(SceneEditor<S> editor) : editor_(std::move(editor)) {}
  Result<std::uint64_t> set(std::string_view effect, std::string_view keys) override {
    return editor_.set(effect, keys);
  }
  Result<std::uint64_t> add(std::string_view kind, std::string_view keys) override { return editor_.add(kind, keys); }
  Result<std::uint64_t> remove(std::string_view effect) override { return editor_.remove(effect); }
  Result<std::uint64_t> load(std::string_view text, std::string name) override {
    return editor_.load(text, std::move(name));
  }
  Result<std::uint64_t> fire(std::string_view effect, std::string_view event, double value) override {
    return editor_.fire(effect, event, value);
  }
  std::uint64_t applied() const override { return editor_.applied(); }
  std::string scene_json() const override;

 private:
  SceneEditor<S> editor_;
};

struct ControlOptions {
  std::string token;                         ///< required in the hello; never empty
  double max_messages_per_s = 200.0;         ///< sustained, per connection (a token bucket)
  double burst_messages = 50.0;              ///< the bucket's size
  std::size_t max_message_bytes = 1U << 16;  ///< larger messages are refused (the socket's limit too)
};

/// A fresh token: 128 bits from the system's random source, as 32 hex digits.
std::string random_token();

/// One connection's conversation. Not thread-safe: the server's thread calls it.
class ControlSession {
 public:
  ControlSession(SceneControl& control, const ControlOptions& options) : control_(control), options_(options) {}

  struct Reply {
    std::string text;    ///< the JSON reply to send
    bool close = false;  ///< then close the connection (a failed hello)
  };
  /// One message received at `now_s` (seconds, any monotonic origin). Never throws. Its cost
  /// is linear in the message's size (at most max_message_bytes, nested at most
  /// kControlMaxDepth levels), and an error's reply is at most about kControlMaxErrorBytes.
  Reply on_message(std::string_view text, double now_s);

  bool authenticated() const noexcept { return authenticated_; }
  std::uint64_t refused() const noexcept { return refused_; }
  /// Changes of the scene this session has sent (set, add, remove, load that passed).
  std::uint64_t changes() const noexcept { return changes_; }

 private:
  SceneControl& control_;
  ControlOptions options_;
  bool authenticated_ = false;
  double tokens_ = -1.0;  ///< rate limit bucket (-1: full, not started)
  double last_s_ = 0.0;
  std::uint64_t refused_ = 0;
  std::uint64_t changes_ = 0;
};

}  // namespace toonforce::viewer
