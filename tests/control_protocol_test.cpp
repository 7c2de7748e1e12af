// SPDX-License-Identifier: Apache-2.0
// The control protocol without a socket (tools/viewer/control_protocol.hpp): what a message
// becomes, with time given by the test (the rate limit is counted in the messages' own times).

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "toonforce/viewer/control_protocol.hpp"

namespace toonforce::viewer {
namespace {

/// Records what the protocol asked for; answers ok.
class Recorder final : public SceneControl {
 public:
  Result<std::uint64_t> set(std::string_view effect, std::string_view keys) override {
    if (effect == "echo") return Error{fmt::format("the scene reader quotes it all: {}", keys)};
    calls.push_back("set " + std::string(effect) + "\n" + std::string(keys));
    return ++sequence;
  }
  Result<std::uint64_t> add(std::string_view kind, std::string_view keys) override {
    calls.push_back("add " + std::string(kind) + "\n" + std::string(keys));
    return ++sequence;
  }
  Result<std::uint64_t> remove(std::string_view effect) override {
    calls.push_back("remove " + std::string(effect));
    return ++sequence;
  }
  Result<std::uint64_t> load(std::string_view, std::string name) override {
    calls.push_back("load " + name);
    return ++sequence;
  }
  Result<std::uint64_t> fire(std::string_view effect, std::string_view event, double value) override {
    calls.push_back(fmt::format("fire {} {} {}", effect, event, value));
    return ++sequence;
  }
  std::uint64_t applied() const override { return sequence; }
  std::string scene_json() const override { return R"({"effects":[]})"; }
  std::vector<std::string> calls;
  std::uint64_t sequence = 0;
};

ControlOptions options() {
  ControlOptions o;
  o.token = "t0k3n";
  o.max_messages_per_s = 10.0;
  o.burst_messages = 5.0;
  o.max_message_bytes = 200;
  return o;
}

TEST(ControlProtocol, KeysBecomeTheTomlTheSceneReaderChecks) {
  Recorder r;
  ControlSession s(r, options());
  ASSERT_NE(s.on_message(R"({"type":"hello","version":1,"token":"t0k3n"})", 0.0).text.find("welcome"),
            std::string::npos);
  const auto reply = s.on_message(
      R"({"type":"set","effect":"surface1","keys":{"stiffness":800,"rearm":1e-05,"point":[0,0.5,-2],"sine":"t\"x","impact":{"duration":0.1}}})",
      0.0);
  EXPECT_NE(reply.text.find(R"("type":"ok")"), std::string::npos) << reply.text;
  ASSERT_EQ(r.calls.size(), 1U);
  // Every number reads back as the same double; strings are escaped; objects are inline tables.
  EXPECT_NE(r.calls[0].find("\"stiffness\" = 800\n"), std::string::npos) << r.calls[0];
  EXPECT_NE(r.calls[0].find("\"rearm\" = 1e-05\n"), std::string::npos) << r.calls[0];
  EXPECT_NE(r.calls[0].find("\"point\" = [0, 0.5, -2]\n"), std::string::npos) << r.calls[0];
  EXPECT_NE(r.calls[0].find("\"sine\" = \"t\\\"x\"\n"), std::string::npos) << r.calls[0];
  EXPECT_NE(r.calls[0].find("\"impact\" = {\"duration\" = 0.1}\n"), std::string::npos) << r.calls[0];
  // null has no TOML form: refused, nothing called.
  EXPECT_NE(s.on_message(R"({"type":"set","effect":"surface1","keys":{"stiffness":null}})", 0.0).text.find("null"),
            std::string::npos);
  EXPECT_EQ(r.calls.size(), 1U);
}

TEST(ControlProtocol, TheRateLimitIsABucketOfMessagesRefilledWithTime) {
  Recorder r;
  ControlSession s(r, options());
  ASSERT_FALSE(s.on_message(R"({"type":"hello","version":1,"token":"t0k3n"})", 0.0).close);
  // The hello took one of 5; 4 more at the same instant pass, the next is refused.
  for (int i = 0; i < 4; ++i) {
    EXPECT_NE(s.on_message(R"({"type":"remove","effect":"x"})", 0.0).text.find("ok"), std::string::npos) << i;
  }
  EXPECT_NE(s.on_message(R"({"type":"remove","effect":"x"})", 0.0).text.find("rate limit"), std::string::npos);
  EXPECT_EQ(r.calls.size(), 4U) << "the refused one changed nothing";
  // 10 a second: 0.1 s later one more passes, and not two.
  EXPECT_NE(s.on_message(R"({"type":"remove","effect":"x"})", 0.1).text.find("ok"), std::string::npos);
  EXPECT_NE(s.on_message(R"({"type":"remove","effect":"x"})", 0.1).text.find("rate limit"), std::string::npos);
  EXPECT_EQ(r.calls.size(), 5U);
}

TEST(ControlProtocol, TooLargeOrBeforeTheHelloIsRefusedAndChangesNothing) {
  Recorder r;
  ControlSession s(r, options());
  const auto early = s.on_message(R"({"type":"fire","effect":"surface1","event":"impact","value":1})", 0.0);
  EXPECT_TRUE(early.close);
  EXPECT_FALSE(s.authenticated());
  const auto wrong = s.on_message(R"({"type":"hello","version":1,"token":"t0k3"})", 0.0);
  EXPECT_TRUE(wrong.close);
  EXPECT_NE(wrong.text.find("wrong token"), std::string::npos);
  ASSERT_FALSE(s.on_message(R"({"type":"hello","version":1,"token":"t0k3n"})", 0.0).close);
  const std::string big = R"({"type":"load","toml":")" + std::string(300, 'x') + R"("})";
  EXPECT_NE(s.on_message(big, 0.0).text.find("at most 200"), std::string::npos);
  EXPECT_TRUE(r.calls.empty());
}

const std::string kHello = R"({"type":"hello","version":1,"token":"t0k3n"})";

/// Options with room for big messages and no rate limit in the way.
ControlOptions roomy() {
  ControlOptions o = options();
  o.max_message_bytes = 1U << 16;
  o.burst_messages = 1e6;
  o.max_messages_per_s = 1e6;
  return o;
}

std::string nested(std::size_t levels, const std::string& open, const std::string& inner, const std::string& close) {
  std::string out;
  for (std::size_t i = 0; i < levels; ++i) out += open;
  out += inner;
  for (std::size_t i = 0; i < levels; ++i) out += close;
  return out;
}

// Keys nested 20,000 arrays deep (40 KB) overflowed the stack in the JSON to TOML
// conversion (SIGSEGV); 10,800 objects deep copied the key path at every level (~244 MB).
// The depth is counted in one pass over the text before anything is parsed.
TEST(ControlProtocol, NestingDeeperThanTheLimitIsRefusedBeforeItIsParsed) {
  Recorder r;
  ControlSession s(r, roomy());
  ASSERT_FALSE(s.on_message(kHello, 0.0).close);
  // The message is level 1, "keys" level 2: 30 arrays inside reach the limit, 31 pass it.
  const auto at_limit = s.on_message(
      R"({"type":"set","effect":"e","keys":{"a":)" + nested(kControlMaxDepth - 2, "[", "1", "]") + "}}", 0.0);
  EXPECT_NE(at_limit.text.find(R"("type":"ok")"), std::string::npos) << at_limit.text.substr(0, 200);
  const auto beyond = s.on_message(
      R"({"type":"set","effect":"e","keys":{"a":)" + nested(kControlMaxDepth - 1, "[", "1", "]") + "}}", 0.0);
  EXPECT_NE(beyond.text.find("at most 32 levels"), std::string::npos) << beyond.text.substr(0, 200);
  const auto arrays =
      s.on_message(R"({"type":"set","effect":"e","keys":{"a":)" + nested(20000, "[", "1", "]") + "}}", 0.0);
  EXPECT_NE(arrays.text.find("at most 32 levels"), std::string::npos) << arrays.text.substr(0, 200);
  const auto objects =
      s.on_message(R"({"type":"set","effect":"e","keys":)" + nested(10800, R"({"k":)", "1", "}") + "}", 0.0);
  EXPECT_NE(objects.text.find("at most 32 levels"), std::string::npos) << objects.text.substr(0, 200);
  // Brackets inside strings (escaped quotes too) are text, not nesting.
  const auto in_string =
      s.on_message(R"({"type":"set","effect":"e","keys":{"name":"\"[[[[)" + std::string(100, '[') + R"("}})", 0.0);
  EXPECT_NE(in_string.text.find(R"("type":"ok")"), std::string::npos) << in_string.text.substr(0, 200);
  EXPECT_EQ(r.calls.size(), 2U);
  EXPECT_FALSE(s.on_message(R"({"type":"status"})", 0.0).close) << "the connection carries on";
}

// The spec closes the connection (1008) on any first message that is not a good
// hello; not JSON, not an object or no type got an error and the connection stayed open.
TEST(ControlProtocol, AnyRefusedFirstMessageClosesTheConnection) {
  for (const std::string& first :
       {std::string("{not json"), std::string("[1,2]"), std::string("42"), std::string(R"({"id":1})"),
        std::string(R"({"type":7})"), std::string(R"({"type":"teleport"})"), std::string(R"({"type":"status","x":1})"),
        std::string(R"({"type":"hello","version":1,"token":"t0k3n","id":[1]})")}) {
    Recorder r;
    ControlSession s(r, roomy());
    const auto reply = s.on_message(first, 0.0);
    EXPECT_TRUE(reply.close) << first << " -> " << reply.text;
    EXPECT_NE(reply.text.find(R"("type":"error")"), std::string::npos) << first;
    EXPECT_FALSE(s.authenticated());
  }
}

// "id": null was not echoed (presence is what counts); an id is short or refused;
// a reply refused by the rate limit carries the id too.
TEST(ControlProtocol, TheIdIsEchoedWhenPresentShortOrRefused) {
  Recorder r;
  ControlOptions o = roomy();
  o.burst_messages = 2.0;
  o.max_messages_per_s = 1.0;
  ControlSession s(r, o);
  const auto welcome =
      nlohmann::json::parse(s.on_message(R"({"type":"hello","version":1,"token":"t0k3n","id":null})", 0.0).text);
  ASSERT_EQ(welcome["type"], "welcome");
  EXPECT_TRUE(welcome.contains("id") && welcome["id"].is_null()) << welcome.dump();
  const std::string id128(kControlMaxIdBytes, 'i');
  const auto ok = nlohmann::json::parse(s.on_message(R"({"type":"status","id":")" + id128 + R"("})", 0.0).text);
  EXPECT_EQ(ok["id"], id128);
  const auto long_id = nlohmann::json::parse(s.on_message(R"({"type":"status","id":")" + id128 + R"(x"})", 0.0).text);
  EXPECT_EQ(long_id["type"], "error");
  EXPECT_FALSE(long_id.contains("id"));
  EXPECT_NE(long_id["message"].get<std::string>().find("at most 128 bytes"), std::string::npos);
  const auto object_id = nlohmann::json::parse(s.on_message(R"({"type":"status","id":{"a":1}})", 0.0).text);
  EXPECT_EQ(object_id["type"], "error");
  EXPECT_FALSE(object_id.contains("id"));
  // The bucket of 2 is empty now (hello, status; refused ids took nothing): limited, with the id.
  const auto limited = nlohmann::json::parse(s.on_message(R"({"type":"status","id":7})", 0.0).text);
  ASSERT_EQ(limited["type"], "error");
  EXPECT_NE(limited["message"].get<std::string>().find("rate limit"), std::string::npos);
  EXPECT_EQ(limited["id"], 7);
}

// With a key given twice the last one won, so "token":"wrong","token":"<the token>"
// passed; a NUL byte ended the text the parser read. Both are refused.
TEST(ControlProtocol, DuplicateKeysAndNulBytesAreRefused) {
  {
    Recorder r;
    ControlSession s(r, roomy());
    const auto twice = s.on_message(R"({"type":"hello","version":1,"token":"wrong","token":"t0k3n"})", 0.0);
    EXPECT_TRUE(twice.close);
    EXPECT_FALSE(s.authenticated());
    EXPECT_NE(twice.text.find("'token' is given twice"), std::string::npos) << twice.text;
  }
  Recorder r;
  ControlSession s(r, roomy());
  const auto nul =
      s.on_message(std::string(R"({"type":"hello","version":1,"token":"t0k3n"})") + std::string(1, '\0') + "x", 0.0);
  EXPECT_TRUE(nul.close);
  EXPECT_NE(nul.text.find("NUL"), std::string::npos) << nul.text;
  Recorder r2;
  ControlSession s2(r2, roomy());
  ASSERT_FALSE(s2.on_message(kHello, 0.0).close);
  // At any level; the same key in two different objects is fine.
  const auto deep =
      s2.on_message(R"({"type":"set","effect":"e","keys":{"impact":{"duration":0.1,"duration":0.2}}})", 0.0);
  EXPECT_NE(deep.text.find("'duration' is given twice"), std::string::npos) << deep.text;
  const auto apart = s2.on_message(
      R"({"type":"set","effect":"e","keys":{"a":{"duration":0.1},"b":{"duration":0.2},"duration":1}})", 0.0);
  EXPECT_NE(apart.text.find(R"("type":"ok")"), std::string::npos) << apart.text;
  EXPECT_EQ(r2.calls.size(), 1U);
}

// Error replies echoed the type, a field or a key whole (up to 64 KiB each), which
// a client that never reads turned into memory. What a reply quotes is cut short.
TEST(ControlProtocol, ARefusalQuotesAShortPrefixOfWhatItRefuses) {
  Recorder r;
  ControlSession s(r, roomy());
  ASSERT_FALSE(s.on_message(kHello, 0.0).close);
  const std::string big(60000, 'x');
  for (const std::string& message :
       {R"({"type":")" + big + R"("})", R"({"type":"status",")" + big + R"(":1})",
        R"({"type":"set","effect":"e","keys":{")" + big + R"(":null}})",
        R"({"type":"set","effect":"echo","keys":{")" + big + R"(":1}})",
        R"({"type":"set","effect":"e","keys":{"a":{"a":1,"a":)" + std::string(1, '"') + big + R"("}}})"}) {
    const auto reply = s.on_message(message, 0.0);
    EXPECT_NE(reply.text.find(R"("type":"error")"), std::string::npos) << reply.text.substr(0, 200);
    EXPECT_LE(reply.text.size(), kControlMaxErrorBytes + 200) << reply.text.substr(0, 200);
  }
}

TEST(ControlProtocol, TokensAreFreshAndLongEnough) {
  const std::string a = random_token();
  EXPECT_EQ(a.size(), 32U);
  EXPECT_NE(a, random_token());
}

}  // namespace
}  // namespace toonforce::viewer
