// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/template.hpp"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

namespace toonforce::report {

namespace {

bool is_name_char(char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_'; }

}  // namespace

Result<std::string> render(const Template& tmpl, const std::vector<TemplateValue>& values) {
  for (std::size_t i = 0; i < values.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (values[i].first == values[j].first)
        return Error{fmt::format("template {}: the value of {{{{{}}}}} is given twice", tmpl.name, values[i].first)};
    }
  }
  std::vector<bool> used(values.size(), false);
  const std::string_view text = tmpl.text;
  std::string out;
  out.reserve(text.size());
  std::size_t at = 0;
  while (true) {
    const auto open = text.find("{{", at);
    if (open == std::string_view::npos) {
      out.append(text.substr(at));
      break;
    }
    out.append(text.substr(at, open - at));
    std::size_t end = open + 2;
    while (end < text.size() && is_name_char(text[end])) ++end;
    if (end == open + 2 || text.substr(end, 2) != "}}") {
      return Error{
          fmt::format("template {}: `{{{{` at offset {} does not open a placeholder {{{{name}}}}", tmpl.name, open)};
    }
    const std::string_view name = text.substr(open + 2, end - open - 2);
    const auto value = std::find_if(values.begin(), values.end(), [&](const auto& v) { return v.first == name; });
    if (value == values.end())
      return Error{fmt::format("template {}: no value for the placeholder {{{{{}}}}}", tmpl.name, name)};
    used[static_cast<std::size_t>(value - values.begin())] = true;
    out.append(value->second);
    at = end + 2;
  }
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!used[i])
      return Error{fmt::format("template {}: a value for {{{{{}}}}}, which it has no placeholder for", tmpl.name,
                               values[i].first)};
  }
  return out;
}

std::string render_prose(const Template& tmpl, const std::vector<TemplateValue>& values) {
  auto text = render(tmpl, values);
  if (!text) throw std::logic_error(text.error());
  return std::move(text).value();
}

}  // namespace toonforce::report
