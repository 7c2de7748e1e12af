// SPDX-License-Identifier: Apache-2.0
// libFuzzer target: the control server's message handler (ControlSession::on_message,
// docs/spec/control-protocol.md) over a real scene editor, so changes that parse go on through
// the JSON to TOML conversion and the scene files' reader. The first byte chooses before the
// hello (the message is the connection's first) or after it; the rest is one message, up to
// 64 KiB. Any bytes must give exactly one bounded reply, never a crash, a sanitizer report, an
// exception or a hang (keys nested 20,000 deep crashed the run).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>
#include <string_view>

#include "toonforce/viewer/control_protocol.hpp"

namespace {

constexpr std::string_view kScene =
    "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1000\n"
    "[surface.impact]\nrecoil_gain = 300\noscillation_gain = 900\nduration = 0.1\nfrequency = 30\n";

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace toonforce;
  using namespace toonforce::viewer;
  if (size == 0 || size > (1U << 16) + 1) return -1;
  const bool after_hello = (data[0] & 1U) != 0;
  const std::string_view message(reinterpret_cast<const char*>(data + 1), size - 1);
  // Every input starts from the same scene and an empty mailbox: the editor is made again after
  // an input it took a change from (opening it is most of an input's cost, and most inputs
  // are refused).
  static std::unique_ptr<SceneMailbox<RuntimeScene<double>>> mailbox;
  static std::unique_ptr<EditorControl<double>> control_ptr;
  if (!control_ptr) {
    control_ptr.reset();
    mailbox = std::make_unique<SceneMailbox<RuntimeScene<double>>>();
    auto editor = SceneEditor<double>::open(kScene, "fuzz.toml", *mailbox);
    if (!editor) std::abort();
    control_ptr = std::make_unique<EditorControl<double>>(std::move(editor.value()));
  }
  EditorControl<double>& control = *control_ptr;
  ControlOptions options;
  options.token = "fuzz-token";
  ControlSession session(control, options);
  if (after_hello) {
    const auto welcome = session.on_message(R"({"type":"hello","version":1,"token":"fuzz-token"})", 0.0);
    if (welcome.close || !session.authenticated()) std::abort();
  }
  const auto reply = session.on_message(message, 0.0);
  if (reply.text.find(R"("type":"ok")") != std::string::npos) control_ptr.reset();  // the scene or mailbox changed
  // Bounded: an error's reply quotes at most a short prefix of what it refuses (JSON's escapes
  // make a byte at most 6).
  if (reply.text.find(R"("type":"error")") != std::string::npos &&
      reply.text.size() > 6 * (kControlMaxErrorBytes + 3 + kControlMaxIdBytes) + 64) {
    std::abort();
  }
  if (!after_hello && !session.authenticated() && !reply.close) std::abort();  // a refused first message closes
  return 0;
}
