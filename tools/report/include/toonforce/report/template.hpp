// SPDX-License-Identifier: Apache-2.0
#pragma once
// The report's prose lives in Markdown templates (tools/report/templates/*.md.in), compiled in
// by CMake (tools/report/cmake/embed_templates.cmake: toonforce/report/templates.hpp); the code
// fills their `{{name}}` placeholders with what it computes (commands, figures, tables).

#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "toonforce/common/result.hpp"

namespace toonforce::report {

/// One template: its file name (for errors) and its text, as the file holds it.
struct Template {
  std::string_view name;
  std::string_view text;
};

/// A placeholder's name and the text that replaces it.
using TemplateValue = std::pair<std::string_view, std::string>;

/// `tmpl` with every `{{name}}` replaced by its value (a name may appear more than once; values
/// are not themselves expanded). An error, naming the template and the placeholder, when a
/// placeholder has no value, a value is given twice or is never used, or a `{{` is not a
/// placeholder (`{{` followed by lower-case letters, digits or `_`, and `}}`): nothing is left
/// unfilled or silently dropped.
Result<std::string> render(const Template& tmpl, const std::vector<TemplateValue>& values);

/// `render` for a template compiled in, filled by code that always gives the same names: a
/// mismatch is that code's bug, not an input's, so it throws std::logic_error (render's
/// message) rather than returning an error every caller would have to pass on.
std::string render_prose(const Template& tmpl, const std::vector<TemplateValue>& values);

}  // namespace toonforce::report
