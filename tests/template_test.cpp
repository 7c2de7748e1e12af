// SPDX-License-Identifier: Apache-2.0
// The report's prose is to live in Markdown templates with `{{name}}` placeholders: the
// renderer fills each one and refuses to leave one unfilled or to drop a value.
#include <gtest/gtest.h>

#include <string>
#include <string_view>
#include <vector>

#include "toonforce/report/template.hpp"

namespace toonforce::report {
namespace {

constexpr Template kGreeting{"greeting.md.in", "# {{title}}\n\n{{who}} ran `{{command}}` for {{who}}.\n"};

TEST(Template, EveryPlaceholderIsReplacedByItsValueAndTheRestIsKeptByteForByte) {
  const auto text = render(kGreeting, {{"title", "Hello"}, {"who", "a {{b}}"}, {"command", ""}});
  ASSERT_TRUE(text) << text.error();
  // A value's own braces are not expanded.
  EXPECT_EQ(text.value(), "# Hello\n\na {{b}} ran `` for a {{b}}.\n");
  EXPECT_EQ(render(Template{"plain.md.in", "no placeholders {here} }}\n"}, {}).value(), "no placeholders {here} }}\n");
}

TEST(Template, APlaceholderWithoutAValueIsAnErrorNamingItAndTheTemplate) {
  const auto text = render(kGreeting, {{"title", "Hello"}, {"who", "me"}});
  ASSERT_FALSE(text);
  EXPECT_NE(text.error().find("greeting.md.in"), std::string::npos) << text.error();
  EXPECT_NE(text.error().find("{{command}}"), std::string::npos) << text.error();
}

TEST(Template, AValueNoPlaceholderUsesIsAnErrorNamingIt) {
  const auto text = render(kGreeting, {{"title", "Hello"}, {"who", "me"}, {"command", "run"}, {"colour", "red"}});
  ASSERT_FALSE(text);
  EXPECT_NE(text.error().find("greeting.md.in"), std::string::npos) << text.error();
  EXPECT_NE(text.error().find("{{colour}}"), std::string::npos) << text.error();
  const auto twice = render(kGreeting, {{"title", "a"}, {"who", "b"}, {"command", "c"}, {"title", "d"}});
  ASSERT_FALSE(twice);
  EXPECT_NE(twice.error().find("{{title}}"), std::string::npos) << twice.error();
}

TEST(Template, ABraceOpeningNoPlaceholderIsAnError) {
  for (const char* text : {"a {{ b }}", "a {{B}}", "a {{b", "a {{}}"}) {
    const auto r = render(Template{"odd.md.in", text}, {{"b", "x"}});
    EXPECT_FALSE(r) << text;
  }
}

}  // namespace
}  // namespace toonforce::report
