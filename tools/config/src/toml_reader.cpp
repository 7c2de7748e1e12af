// SPDX-License-Identifier: Apache-2.0
#include "toonforce/config/toml_reader.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <system_error>

#include <fmt/format.h>

namespace toonforce {

void ErrorList::add(const toml::source_region& where, std::string_view path, std::string_view problem) {
  add(where.begin.line, path, problem);
}

void ErrorList::add(std::uint32_t line, std::string_view path, std::string_view problem) {
  ++count_;
  if (entries_.size() >= kKept) return;
  if (line == 0) {  // about the whole file (it cannot be read): no line to name
    entries_.push_back(
        {line, path.empty() ? fmt::format("{}: {}", file_, problem) : fmt::format("{}: {}: {}", file_, path, problem)});
  } else if (path.empty()) {
    entries_.push_back({line, fmt::format("{}:{}: {}", file_, line, problem)});
  } else {
    entries_.push_back({line, fmt::format("{}:{}: {}: {}", file_, line, path, problem)});
  }
}

std::vector<std::string> ErrorList::messages() const {
  std::vector<const Entry*> sorted;
  sorted.reserve(entries_.size());
  for (const auto& e : entries_) sorted.push_back(&e);
  std::stable_sort(sorted.begin(), sorted.end(), [](const Entry* a, const Entry* b) { return a->line < b->line; });
  std::vector<std::string> out;
  out.reserve(sorted.size());
  for (const Entry* e : sorted) out.push_back(e->message);
  return out;
}

std::string ErrorList::text() const {
  const std::vector<std::string> sorted = messages();
  std::string out;
  for (std::size_t i = 0; i < sorted.size() && i < kShown; ++i) {
    out += sorted[i];
    out += '\n';
  }
  if (count_ > kShown) {
    out += fmt::format("{}: {} more error(s) not shown; fix the {} above (by line) first\n", file_, count_ - kShown,
                       kShown);
  }
  return out;
}

std::string printable(std::string_view text, std::size_t max_chars) {
  std::string out;
  const std::size_t shown = std::min(text.size(), max_chars);
  for (std::size_t i = 0; i < shown; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x20 || c == 0x7F) {
      out += fmt::format("\\x{:02X}", c);
    } else {
      out += static_cast<char>(c);
    }
  }
  if (text.size() > max_chars) out += fmt::format("... ({} bytes)", text.size());
  return out;
}

namespace {

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0U : 1U)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

std::string_view type_name(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::table: return "a table";
    case toml::node_type::array: return "an array";
    case toml::node_type::string: return "a string";
    case toml::node_type::integer: return "an integer";
    case toml::node_type::floating_point: return "a number";
    case toml::node_type::boolean: return "a boolean";
    case toml::node_type::date: return "a date";
    case toml::node_type::time: return "a time";
    case toml::node_type::date_time: return "a date-time";
    case toml::node_type::none: break;
  }
  return "nothing";
}

std::string_view range_text(Range range) {
  switch (range) {
    case Range::kPositive: return "> 0";
    case Range::kNonNegative: return ">= 0";
    case Range::kNonPositive: return "<= 0";
    case Range::kAny: break;
  }
  return "";
}

}  // namespace

std::optional<std::string> nearest_key(std::string_view key, std::span<const std::string> known) {
  std::optional<std::string> best;
  std::size_t best_distance = 0;
  // A typo changes a few characters; beyond that a suggestion is noise.
  const std::size_t allowed = std::max<std::size_t>(2, key.size() / 3);
  for (const auto& candidate : known) {
    // The distance is at least the difference in length: a 20 MB key is never compared in full.
    const std::size_t length_gap =
        key.size() > candidate.size() ? key.size() - candidate.size() : candidate.size() - key.size();
    if (length_gap > allowed) continue;
    const std::size_t d = edit_distance(key, candidate);
    if (!best || d < best_distance) {
      best = candidate;
      best_distance = d;
    }
  }
  if (best && best_distance <= allowed) return best;
  return std::nullopt;
}

TableReader::TableReader(const toml::table& table, std::string path, ErrorList& errors, ScalarKind scalar)
    : table_(table), path_(std::move(path)), errors_(errors), scalar_(scalar) {}

std::string TableReader::key_path(std::string_view key) const {
  if (path_.empty()) return std::string(key);
  if (key.empty()) return path_;
  return fmt::format("{}.{}", path_, key);
}

std::uint32_t TableReader::line() const { return table_.source().begin.line; }

std::uint32_t TableReader::line_of(std::string_view key) const {
  if (const toml::node* node = table_.get(key)) return node->source().begin.line;
  return line();
}

void TableReader::error(std::string_view key, std::string_view problem) {
  const std::size_t dot = key.find('.');
  if (dot != std::string_view::npos) {  // a key of a sub-table: its own line
    const toml::node* sub = table_.get(key.substr(0, dot));
    if (const toml::table* t = sub != nullptr ? sub->as_table() : nullptr) {
      const toml::node* node = t->get(key.substr(dot + 1));
      errors_.add(node != nullptr ? node->source().begin.line : t->source().begin.line, key_path(key), problem);
      return;
    }
  }
  errors_.add(line_of(key), key_path(key), problem);
}

const toml::node* TableReader::take(std::string_view key) {
  known_.emplace_back(key);
  const toml::node* node = table_.get(key);
  if (node != nullptr) read_.emplace_back(key);
  return node;
}

std::optional<double> TableReader::to_number(std::string_view key, const toml::node& node, Range range,
                                             std::string_view hint) {
  double value = 0.0;
  if (const auto* f = node.as_floating_point()) {
    value = f->get();
  } else if (const auto* i = node.as_integer()) {
    value = static_cast<double>(i->get());
  } else {
    error(key, fmt::format("must be a number, not {}", type_name(node)));
    return std::nullopt;
  }
  if (!std::isfinite(value)) {
    error(key, fmt::format("must be a finite number (got {})", value));
    return std::nullopt;
  }
  if (!in_range(value, range)) {
    error(key, fmt::format("must be {} (got {}){}{}", range_text(range), value, hint.empty() ? "" : "; ", hint));
    return std::nullopt;
  }
  // No quantity of a scene or a hand script comes near 1e12 in SI units; beyond it the force
  // laws' products (stiffness x depth, squared by the clamp) overflow a float and soon a
  // double (stiffness = 1e308 made the wall vanish).
  if (std::abs(value) > kMaxMagnitude) {
    error(key, fmt::format("{:g} is too large: allowed magnitudes are up to {:g} (larger ones overflow the force laws)",
                           value, kMaxMagnitude));
    return std::nullopt;
  }
  if (scalar_ == ScalarKind::kQ16_16) {
    if (!representable<Q16_16>(value)) {
      error(key, fmt::format("{} is outside the Q16.16 range (about +-32768)", value));
      return std::nullopt;
    }
    if (value != 0.0 && Q16_16::from_double(value).raw() == 0) {
      error(key, fmt::format("{} rounds to 0 in Q16.16 (resolution 1.5e-5)", value));
      return std::nullopt;
    }
  } else if (scalar_ == ScalarKind::kFloat) {
    if (!representable<float>(value)) {
      error(key, fmt::format("{} is outside the float range", value));
      return std::nullopt;
    }
    if (value != 0.0 && static_cast<float>(value) == 0.0F) {
      error(key, fmt::format("{} rounds to 0 in float", value));
      return std::nullopt;
    }
  }
  return value;
}

std::optional<double> TableReader::required_number(std::string_view key, Range range, std::string_view unit,
                                                   std::string_view hint) {
  const toml::node* node = take(key);
  if (node == nullptr) {
    error("", fmt::format("missing required key '{}'{}{}", key, unit.empty() ? "" : " ", unit));
    return std::nullopt;
  }
  return to_number(key, *node, range, hint);
}

double TableReader::number_or(std::string_view key, double fallback, Range range, std::string_view hint) {
  const toml::node* node = take(key);
  if (node == nullptr) return fallback;
  return to_number(key, *node, range, hint).value_or(fallback);
}

std::optional<double> TableReader::optional_number(std::string_view key, Range range) {
  const toml::node* node = take(key);
  if (node == nullptr) return std::nullopt;
  return to_number(key, *node, range);
}

std::optional<Vec3<double>> TableReader::required_vec3(std::string_view key, std::string_view unit) {
  const toml::node* node = take(key);
  if (node == nullptr) {
    error("", fmt::format("missing required key '{}'{}{}", key, unit.empty() ? "" : " ", unit));
    return std::nullopt;
  }
  const toml::array* array = node->as_array();
  if (array == nullptr || array->size() != 3) {
    error(key,
          fmt::format("must be an array of three numbers{}{}, like [0.0, 0.0, 1.0]", unit.empty() ? "" : " ", unit));
    return std::nullopt;
  }
  double v[3] = {};
  for (std::size_t i = 0; i < 3; ++i) {
    const auto component = to_number(key, *array->get(i), Range::kAny);
    if (!component) return std::nullopt;
    v[i] = *component;
  }
  return Vec3<double>{v[0], v[1], v[2]};
}

std::optional<Vec3<double>> TableReader::optional_vec3(std::string_view key, std::string_view unit) {
  if (table_.get(key) == nullptr) {
    known_.emplace_back(key);
    return std::nullopt;
  }
  return required_vec3(key, unit);
}

std::optional<std::int64_t> TableReader::optional_integer(std::string_view key, std::int64_t min_value) {
  const toml::node* node = take(key);
  if (node == nullptr) return std::nullopt;
  std::optional<std::int64_t> value;
  if (const auto* i = node->as_integer()) {
    value = i->get();
  } else if (const auto* f = node->as_floating_point()) {
    const double v = f->get();
    if (std::isfinite(v) && v == std::floor(v) && std::abs(v) < 9e15) value = static_cast<std::int64_t>(v);
  }
  if (!value) {
    error(key, fmt::format("must be a whole number, not {}", node->is_number() ? "a fraction" : type_name(*node)));
    return std::nullopt;
  }
  if (*value < min_value) {
    error(key, fmt::format("must be >= {} (got {})", min_value, *value));
    return std::nullopt;
  }
  return value;
}

std::optional<std::string> TableReader::optional_string(std::string_view key, StringKind kind) {
  const toml::node* node = take(key);
  if (node == nullptr) return std::nullopt;
  if (const auto* s = node->as_string()) {
    // Names and labels end up in summaries, traces and the viewer: no control characters.
    const std::string& text = s->get();
    const bool control = std::any_of(text.begin(), text.end(), [kind](char c) {
      if (kind == StringKind::kText && (c == '\n' || c == '\t')) return false;
      return static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) == 0x7F;
    });
    if (!control) return text;
    error(key, fmt::format("'{}' has a control character: write it without", printable(text)));
    return std::nullopt;
  }
  error(key, fmt::format("must be a string, not {}", type_name(*node)));
  return std::nullopt;
}

std::optional<bool> TableReader::optional_bool(std::string_view key) {
  const toml::node* node = take(key);
  if (node == nullptr) return std::nullopt;
  if (const auto* b = node->as_boolean()) return b->get();
  error(key, fmt::format("must be true or false, not {}", type_name(*node)));
  return std::nullopt;
}

bool TableReader::has(std::string_view key) const { return table_.get(key) != nullptr; }

bool TableReader::reject(std::string_view key, std::string_view problem) {
  if (!has(key)) return false;
  read_.emplace_back(key);  // read, but not "known": no did-you-mean toward it
  error(key, problem);
  return true;
}

const toml::table* TableReader::optional_table(std::string_view key) {
  const toml::node* node = take(key);
  if (node == nullptr) return nullptr;
  if (const auto* t = node->as_table()) return t;
  error(key, fmt::format("must be a table ([{}]), not {}", key_path(key), type_name(*node)));
  return nullptr;
}

std::vector<const toml::table*> TableReader::array_of_tables(std::string_view key) {
  std::vector<const toml::table*> tables;
  const toml::node* node = take(key);
  if (node == nullptr) return tables;
  const toml::array* array = node->as_array();
  if (array == nullptr || !array->is_array_of_tables()) {
    error(key, fmt::format("must be an array of tables: write each as [[{}]]", key_path(key)));
    return tables;
  }
  for (const auto& element : *array) tables.push_back(element.as_table());
  return tables;
}

void TableReader::finish() { finish("table", ""); }

void TableReader::finish(std::string_view what, std::string_view note) {
  for (const auto& [key, node] : table_) {
    const std::string name(key.str());
    if (std::find(read_.begin(), read_.end(), name) != read_.end()) continue;
    const bool tables = node.is_array_of_tables();
    std::string problem = tables ? fmt::format("unknown {} [[{}]]", what, printable(name))
                                 : fmt::format("unknown key '{}'", printable(name));
    if (auto near = nearest_key(name, known_)) {
      problem += fmt::format(" (did you mean '{}'?)", *near);
    } else if (tables && !note.empty()) {
      problem += fmt::format(" ({})", note);
    }
    errors_.add(key.source().begin.line != 0 ? key.source().begin.line : node.source().begin.line, path_, problem);
  }
}

namespace {

/// Length of the valid UTF-8 sequence at text[i], or 0 if it is not one (overlong forms,
/// surrogates and code points above U+10FFFF are invalid).
std::size_t utf8_length(std::string_view text, std::size_t i) {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[k]); };
  const unsigned char b = byte(i);
  std::size_t n = 0;
  std::uint32_t cp = 0;
  if (b < 0x80) return 1;
  if (b >= 0xC2 && b <= 0xDF) {
    n = 2;
    cp = b & 0x1FU;
  } else if (b >= 0xE0 && b <= 0xEF) {
    n = 3;
    cp = b & 0x0FU;
  } else if (b >= 0xF0 && b <= 0xF4) {
    n = 4;
    cp = b & 0x07U;
  } else {
    return 0;
  }
  if (i + n > text.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    if ((byte(i + k) & 0xC0U) != 0x80U) return 0;
    cp = (cp << 6) | (byte(i + k) & 0x3FU);
  }
  const bool overlong = (n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000);
  if (overlong || (cp >= 0xD800 && cp <= 0xDFFF) || cp > 0x10FFFF) return 0;
  return n;
}

/// An upper estimate of a TOML text's nesting, fed one character at a time outside comments and
/// strings, so that no parser recursion ever sees a deep text. A level is each part of the
/// current table header, each part of a dotted key at every open bracket, and each open array
/// or inline table; numbers' dots count until the next separator, which only overstates.
class DepthScan {
 public:
  /// False once the estimate passes kMaxTomlDepth.
  bool on(char c) noexcept {
    const bool line_start = line_start_;
    if (c == '\n') {
      line_start_ = true;
      dots_ = 0;
      if (open_ == 0) committed_ = 0;  // the next top-level key starts afresh
      return true;
    }
    if (c != ' ' && c != '\t' && c != '\r') line_start_ = false;
    switch (c) {
      case '.': ++dots_; break;
      case '=':
        committed_ = committed_ - key_dots_[open_] + dots_;
        key_dots_[open_] = dots_;
        dots_ = 0;
        break;
      case ',': dots_ = 0; break;
      case '[':
      case '{':
        if (in_header_) break;                       // the second '[' of "[[table]]"
        if (c == '[' && open_ == 0 && line_start) {  // a table header
          in_header_ = true;
          header_ = 0;
          committed_ = 0;
          key_dots_[0] = 0;
        } else {
          if (open_ + 1 >= key_dots_.size()) return false;  // deeper than any estimate allows
          ++open_;
          key_dots_[open_] = 0;
        }
        dots_ = 0;
        break;
      case ']':
      case '}':
        if (in_header_) {
          in_header_ = false;
          header_ = dots_ + 2;  // its parts, and the array of a "[[table]]" (an overestimate otherwise)
        } else if (open_ > 0) {
          committed_ -= key_dots_[open_];
          --open_;
        }
        dots_ = 0;
        break;
      default: break;
    }
    return depth() <= kMaxTomlDepth;
  }

 private:
  std::uint32_t depth() const noexcept { return header_ + committed_ + open_ + dots_ + 1; }

  std::array<std::uint32_t, kMaxTomlDepth + 2> key_dots_{};  ///< the key's dots at each open level
  std::uint32_t open_ = 0;                                   ///< arrays and inline tables open
  std::uint32_t committed_ = 0;                              ///< sum of key_dots_[0..open_]
  std::uint32_t header_ = 0;                                 ///< levels of the current table header
  std::uint32_t dots_ = 0;                                   ///< dots since the last separator
  bool in_header_ = false;
  bool line_start_ = true;
};

/// Checks what toml++ 3.3 (Debian 12's) cannot be trusted with: invalid UTF-8, and non-ASCII
/// characters where the parser classifies whitespace (outside comments and strings, and right
/// after a line-ending backslash in a multi-line string). There its whitespace lookup reaches
/// an "unreachable" branch, which is undefined behaviour (marzer/tomlplusplus#190 and #295, found
/// here by tests/fuzz/scene_file_fuzz.cpp). TOML allows non-ASCII only in comments and strings
/// anyway, so rejecting it elsewhere, with its line, costs a valid file nothing.
bool check_text(std::string_view text, ErrorList& errors) {
  enum class State { kNormal, kComment, kBasic, kLiteral, kMultiBasic, kMultiLiteral, kLineEndingBackslash };
  State state = State::kNormal;
  DepthScan depth;
  std::uint32_t line = 1;
  const auto starts = [&](std::size_t i, std::string_view s) { return text.substr(i, s.size()) == s; };
  std::size_t i = 0;
  // Moves past the current character and n - 1 more, counting the newlines among the others.
  const auto skip = [&](std::size_t n) {
    for (std::size_t k = i + 1; k < i + n && k < text.size(); ++k) line += text[k] == '\n' ? 1U : 0U;
    i += n;
  };
  while (i < text.size()) {
    const char c = text[i];
    if (static_cast<unsigned char>(c) >= 0x80) {
      const std::size_t n = utf8_length(text, i);
      if (n == 0) {
        errors.add(line, "",
                   fmt::format("invalid UTF-8 (byte 0x{:02X}); save the file as UTF-8", static_cast<unsigned char>(c)));
        return false;
      }
      if (state == State::kNormal || state == State::kLineEndingBackslash) {
        errors.add(line, "",
                   "a non-ASCII character outside a comment or a string; TOML keys and values are ASCII "
                   "unless quoted");
        return false;
      }
      i += n;
      continue;
    }
    if (c == '\n') ++line;
    if ((state == State::kNormal || (state == State::kComment && c == '\n')) && !depth.on(c)) {
      errors.add(line, "",
                 fmt::format("nested deeper than {} levels (table headers, dotted keys, arrays and inline "
                             "tables counted together); a scene or hand script needs a handful",
                             kMaxTomlDepth));
      return false;
    }
    switch (state) {
      case State::kNormal:
        if (c == '#')
          state = State::kComment;
        else if (starts(i, "\"\"\"")) {
          state = State::kMultiBasic;
          skip(3);
          continue;
        } else if (starts(i, "'''")) {
          state = State::kMultiLiteral;
          skip(3);
          continue;
        } else if (c == '"')
          state = State::kBasic;
        else if (c == '\'')
          state = State::kLiteral;
        break;
      case State::kComment:
        if (c == '\n') state = State::kNormal;
        break;
      case State::kBasic:
        if (c == '\\') {
          skip(2);
          continue;
        }
        if (c == '"' || c == '\n') state = State::kNormal;
        break;
      case State::kLiteral:
        if (c == '\'' || c == '\n') state = State::kNormal;
        break;
      case State::kMultiBasic:
        if (starts(i, "\"\"\"")) {
          state = State::kNormal;
          skip(3);
          continue;
        }
        if (c == '\\') {
          std::size_t k = i + 1;
          while (k < text.size() && (text[k] == ' ' || text[k] == '\t' || text[k] == '\r')) ++k;
          if (k < text.size() && text[k] == '\n') {
            state = State::kLineEndingBackslash;
            skip(1);
            continue;
          }
          skip(2);
          continue;
        }
        break;
      case State::kLineEndingBackslash:  // whitespace and newlines, up to the next character
        if (c != ' ' && c != '\t' && c != '\r' && c != '\n') {
          state = State::kMultiBasic;
          continue;
        }
        break;
      case State::kMultiLiteral:
        if (starts(i, "'''")) {
          state = State::kNormal;
          skip(3);
          continue;
        }
        break;
    }
    skip(1);
  }
  return true;
}

}  // namespace

std::optional<toml::table> parse_toml_file(const std::string& path, ErrorList& errors) {
  // The reason, not a line: it was "FILE:0: cannot open the file for reading".
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    errors.add(0, "", "is a directory, not a TOML file");
    return std::nullopt;
  }
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    errors.add(0, "", fmt::format("cannot be read: {}", std::strerror(errno != 0 ? errno : EIO)));
    return std::nullopt;
  }
  // Read no further than just past the limit: /dev/zero or a huge file costs nothing more.
  std::string text;
  std::array<char, 1U << 16> chunk{};
  while (text.size() <= kMaxTomlBytes && (file.read(chunk.data(), chunk.size()) || file.gcount() > 0)) {
    text.append(chunk.data(), static_cast<std::size_t>(file.gcount()));
  }
  return parse_toml_text(text, errors);
}

std::optional<toml::table> parse_toml_text(std::string_view text, ErrorList& errors) {
  if (text.size() > kMaxTomlBytes) {
    errors.add(0, "", fmt::format("larger than {} MiB; a scene or hand script is a few KiB", kMaxTomlBytes >> 20));
    return std::nullopt;
  }
  if (!check_text(text, errors)) return std::nullopt;
  try {
    return toml::parse(text, errors.file());
  } catch (const toml::parse_error& e) {
    errors.add(e.source(), "", fmt::format("TOML syntax: {}", e.description()));
    return std::nullopt;
  }
}

}  // namespace toonforce
