// The control protocol without a socket (tools/viewer/control_protocol.hpp): what a message
// becomes, with time given by the test (the rate limit is counted in the messages' own times).

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "toonforce/viewer/control_protocol.hpp"

namespace toonforce::viewer {
namespace {

/// Records what the protocol asked for; answers ok.
class Recorder final : public SceneControl {
 public:
  Result<std::uint64_t> set(std::string_view effect, std::string_view keys) override {
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
  ASSERT_NE(s.on_message(R"({"type":"hello","version":1,"token":"t0k3n"})", 0.0).text.find("welcome"), std::string::npos);
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

TEST(ControlProtocol, TokensAreFreshAndLongEnough) {
  const std::string a = random_token();
  EXPECT_EQ(a.size(), 32U);
  EXPECT_NE(a, random_token());
}

}  // namespace
}  // namespace toonforce::viewer
