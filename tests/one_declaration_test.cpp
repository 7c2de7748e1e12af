// SPDX-License-Identifier: Apache-2.0
// What is declared once and listed from there: the built-in effect kinds
// (effects/include/toonforce/effects/builtin.hpp) in every list that names them, and the
// [device] keys (tools/config/src/device_keys.cpp) in the reader and the spec's table.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include <fmt/format.h>

#include "toonforce/config/device_keys.hpp"
#include "toonforce/config/scene_file.hpp"
#include "toonforce/effects/builtin.hpp"
#include "toonforce/effects/scene.hpp"

namespace toonforce {
namespace {

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

const std::string kSource = TOONFORCE_SOURCE_DIR;

// ---- built-in effect kinds ------------------------------------------------------------------

// The run-time scene and the scene files take their kinds from the one list, in its order.
static_assert(std::is_same_v<RuntimeScene<double>, RuntimeSceneOf<double, TOONFORCE_BUILTIN_EFFECTS>>);
static_assert(std::is_same_v<SceneDescription, SceneFileOf<TOONFORCE_BUILTIN_EFFECTS>>);
static_assert(RuntimeScene<double>::kind_count() == BuiltinEffects::kCount);
static_assert(SceneDescription::kKinds == BuiltinEffects::kCount);

template <std::size_t... I>
constexpr bool keys_in_order(std::index_sequence<I...>) {
  return ((RuntimeScene<double>::Kind<I>::kKey == BuiltinEffects::kKeys[I] &&
           SceneDescription::Kind<I>::kKey == BuiltinEffects::kKeys[I] &&
           RuntimeScene<double>::kind_index(BuiltinEffects::kKeys[I]) == I) &&
          ...);
}
static_assert(keys_in_order(std::make_index_sequence<BuiltinEffects::kCount>{}));

TEST(BuiltinEffects, EveryKindIsReadFromAFileByItsKey) {
  // A file naming every kind: each is read into its own list (none refused as unknown).
  const std::string bodies[] = {"point = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1000\n",
                                "point = [0, 0, 0]\nnormal = [0, 0, 1]\naxis = [1, 0, 0]\ngap_min = -0.01\n"
                                "gap_max = 0.01\nstiffness = 1000\nspeed_threshold = 0.08\ntau = 0.02\n"
                                "rearm_height = 0.001\n"};
  static_assert(std::size(bodies) == BuiltinEffects::kCount, "a new built-in kind: add a table of it here");
  std::string text;
  for (std::size_t i = 0; i < BuiltinEffects::kCount; ++i) {
    text += fmt::format("[[{}]]\n{}", BuiltinEffects::kKeys[i], bodies[i]);
  }
  const auto scene = parse_scene(text, "kinds.toml");
  ASSERT_TRUE(scene) << scene.error();
  ASSERT_EQ(scene->order.size(), BuiltinEffects::kCount);
  for (std::size_t i = 0; i < BuiltinEffects::kCount; ++i) EXPECT_EQ(scene->order[i].kind, i);
}

TEST(BuiltinEffects, TheSpecAndTheProtocolNameEveryKind) {
  const std::string interfaces = read_text(kSource + "/docs/spec/interfaces.md");
  const std::string protocol = read_text(kSource + "/docs/spec/control-protocol.md");
  ASSERT_FALSE(interfaces.empty());
  // The control protocol's `add` row lists the kinds it takes.
  const std::size_t add = protocol.find("| `add` | `kind` (");
  ASSERT_NE(add, std::string::npos);
  const std::string add_row = protocol.substr(add, protocol.find('\n', add) - add);
  for (const std::string_view key : BuiltinEffects::kKeys) {
    EXPECT_NE(interfaces.find(fmt::format("[[{}]]", key)), std::string::npos)
        << "docs/spec/interfaces.md has no [[" << key << "]] in its scene-file example";
    EXPECT_NE(add_row.find(fmt::format("\"{}\"", key)), std::string::npos)
        << "docs/spec/control-protocol.md's add row does not name \"" << key << "\": " << add_row;
  }
}

// ---- [device] keys ---------------------------------------------------------------------------

TEST(DeviceKeys, SpecTableIsTheDeclaration) {
  const std::string path = kSource + "/docs/spec/interfaces.md";
  const std::string text = read_text(path);
  const std::string begin = "<!-- BEGIN generated: [device] keys (tools/config/src/device_keys.cpp) -->\n";
  const std::string end = "<!-- END generated: [device] keys -->";
  const std::size_t b = text.find(begin);
  const std::size_t e = text.find(end);
  ASSERT_NE(b, std::string::npos) << path << " has no line " << begin;
  ASSERT_NE(e, std::string::npos) << path << " has no line " << end;
  ASSERT_LT(b, e);
  const std::string spec = text.substr(b + begin.size(), e - b - begin.size());
  const std::string declared = device_keys_markdown();
  // TOONFORCE_WRITE_SPEC=1 writes the declared table into the spec instead of comparing.
  if (const char* write = std::getenv("TOONFORCE_WRITE_SPEC"); write != nullptr && std::string(write) == "1") {
    std::ofstream(path, std::ios::binary) << text.substr(0, b + begin.size()) << declared << text.substr(e);
    GTEST_SKIP() << "wrote the [device] table into " << path;
  }
  EXPECT_EQ(spec, declared) << path << "'s [device] table is not the declaration (tools/config/src/device_keys.cpp); "
                            << "run this test with TOONFORCE_WRITE_SPEC=1 to write it. The declared table:\n"
                            << declared;
}

TEST(DeviceKeys, EveryDeclaredKeyIsReadAndNamedInItsErrors) {
  const std::string floor = "[[surface]]\npoint = [0, 0, 0]\nnormal = [0, 0, 1]\nstiffness = 1000\n";
  std::size_t keys = 0;
  for (const DeviceKey& k : device_keys()) {
    for (const std::string_view key : {k.key, k.upper_key}) {
      if (key.empty()) continue;
      ++keys;
      // A string fits no key's type: the reader must read the key (not call it unknown) and
      // name it, with its line.
      const auto scene = parse_scene(fmt::format("[device]\n{} = \"x\"\n", key) + floor, "bad.toml");
      ASSERT_FALSE(scene) << key;
      EXPECT_NE(scene.error().find(fmt::format("bad.toml:2: device.{}: must be", key)), std::string::npos)
          << scene.error();
      EXPECT_EQ(scene.error().find("unknown key"), std::string::npos) << scene.error();
    }
  }
  EXPECT_EQ(keys, 16u);  // the 16 keys of interfaces.md's table
}

}  // namespace
}  // namespace toonforce
