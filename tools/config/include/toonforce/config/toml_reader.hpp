// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Reading TOML files that people write by hand (scenes, hand scripts) with errors that name
/// the file, the line and the key, and that reject what they do not know: an unknown key, a
/// wrong type, a non-finite number, a value out of range. All errors of a file are collected
/// so one run shows them all. Numbers may be written as integers or floats.

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <toml++/toml.h>

#include "toonforce/effects/schema.hpp"
#include "toonforce/math/scalar_kind.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce {

/// The largest magnitude any number of a scene or hand script may have.
inline constexpr double kMaxMagnitude = 1e12;

// The scalar type a file's numbers must fit (spec effects.md §7: a value outside the Q16.16
// range is an error at load) is a ScalarKind (toonforce/math/scalar_kind.hpp).

/// Where errors go: "FILE:LINE: WHERE.KEY: PROBLEM". Shown sorted by line (the order a person
/// fixes them in, whatever order the reader found them), and at most kShown of them: a file
/// with thousands of errors is not one a person reads to the end, and printing them all took
/// seconds. Every error is counted.
class ErrorList {
 public:
  static constexpr std::size_t kShown = 20;   ///< errors text() shows
  static constexpr std::size_t kKept = 1000;  ///< errors kept for sorting; the rest only counted

  explicit ErrorList(std::string file) : file_(std::move(file)) {}
  void add(const toml::source_region& where, std::string_view path, std::string_view problem);
  void add(std::uint32_t line, std::string_view path, std::string_view problem);
  bool empty() const noexcept { return count_ == 0; }
  std::size_t count() const noexcept { return count_; }  ///< every error added
  /// The errors kept, sorted by line (stable: one line's errors in the order found).
  std::vector<std::string> messages() const;
  /// One error per line, sorted by line; past kShown, one last line says how many more.
  std::string text() const;
  const std::string& file() const noexcept { return file_; }

 private:
  struct Entry {
    std::uint32_t line;
    std::string message;
  };
  std::string file_;
  std::vector<Entry> entries_;
  std::size_t count_ = 0;
};

/// `text` made safe to print inside an error message: control characters (a NUL would cut the
/// message short, an escape sequence would drive the terminal) written as \xNN, and anything
/// past `max_chars` left out with its length said ("kkkk... (20000000 bytes)").
std::string printable(std::string_view text, std::size_t max_chars = 64);

/// What a number must satisfy (the effects' schemas use the same).
using Range = schema::Range;

/// Reads the keys of one table, each at most once; `finish()` reports every key never read.
class TableReader {
 public:
  /// `path` names the table in messages ("surface[2].impact"; empty for the root).
  TableReader(const toml::table& table, std::string path, ErrorList& errors, ScalarKind scalar);

  /// A required number; nullopt (and an error) if missing or invalid. `hint`, if any, follows a
  /// range error ("must be <= 0 (got 2); HINT").
  std::optional<double> required_number(std::string_view key, Range range, std::string_view unit,
                                        std::string_view hint = {});
  /// An optional number with a default; the default on error (the error is recorded).
  double number_or(std::string_view key, double fallback, Range range, std::string_view hint = {});
  /// An optional number without a default.
  std::optional<double> optional_number(std::string_view key, Range range);
  /// A required 3-vector of numbers.
  std::optional<Vec3<double>> required_vec3(std::string_view key, std::string_view unit);
  /// An optional 3-vector of numbers.
  std::optional<Vec3<double>> optional_vec3(std::string_view key, std::string_view unit);
  /// An optional whole number >= `min_value` (a count, not a quantity: no scalar-range check).
  std::optional<std::int64_t> optional_integer(std::string_view key, std::int64_t min_value);
  /// An optional string. A one-line string (a name, a label, a kind: they end up in summaries,
  /// traces and the viewer) may have no control character; a free `text` (a note) may have
  /// new lines and tabs, and no other.
  enum class StringKind : std::uint8_t { kOneLine, kText };
  std::optional<std::string> optional_string(std::string_view key, StringKind kind = StringKind::kOneLine);
  /// An optional boolean (true/false).
  std::optional<bool> optional_bool(std::string_view key);
  /// True if the table has `key` (whether read or not).
  bool has(std::string_view key) const;
  /// If the table has `key`: records `problem` about it, marks it read (so finish() does not
  /// report it a second time as unknown) and returns true. For keys that exist elsewhere in
  /// the format but not here ("'force' does not apply to a move segment").
  bool reject(std::string_view key, std::string_view problem);
  /// An optional sub-table (`[parent.key]`).
  const toml::table* optional_table(std::string_view key);
  /// An optional array of tables (`[[key]]`); its elements, or empty.
  std::vector<const toml::table*> array_of_tables(std::string_view key);

  /// Records an error about `key` (or about the table itself when `key` is empty). A dotted key
  /// ("impact.sine") names a key of a sub-table, reported at that key's line.
  void error(std::string_view key, std::string_view problem);
  /// Line of `key`, or of the table when absent.
  std::uint32_t line_of(std::string_view key) const;
  std::uint32_t line() const;
  const std::string& path() const noexcept { return path_; }
  ErrorList& errors() noexcept { return errors_; }
  ScalarKind scalar() const noexcept { return scalar_; }
  /// Reports keys that were never read, suggesting the nearest known one.
  void finish();
  /// The same, saying of an unknown array of tables `[[key]]` "unknown <what> [[key]]" followed
  /// by `note` (a scene: "unknown effect [[magnet]] (this program reads surface, cliff)").
  void finish(std::string_view what, std::string_view note);

 private:
  const toml::node* take(std::string_view key);
  std::optional<double> to_number(std::string_view key, const toml::node& node, Range range,
                                  std::string_view hint = {});
  std::string key_path(std::string_view key) const;

  const toml::table& table_;
  std::string path_;
  ErrorList& errors_;
  ScalarKind scalar_;
  std::vector<std::string> known_;  // every key asked for, present or not
  std::vector<std::string> read_;   // keys present and read
};

/// The known key nearest to `key` by edit distance, if it is a plausible typo.
std::optional<std::string> nearest_key(std::string_view key, std::span<const std::string> known);

/// The deepest structure a TOML text may have: tables, dotted keys, arrays and inline tables
/// counted together (an upper estimate, see check_text). toonforce's files need fewer than 8;
/// toml++ recurses once per level, and ~32,000 levels overflowed a thread's stack,
/// so the text is measured before the parser sees it.
inline constexpr std::uint32_t kMaxTomlDepth = 64;
/// The largest TOML text read: a scene or hand script is a few KiB.
inline constexpr std::size_t kMaxTomlBytes = std::size_t{16} << 20;

/// Parses a TOML file; on a syntax error, records it and returns nullopt. The size
/// (kMaxTomlBytes) and the depth (kMaxTomlDepth) are checked first, in one pass over the text.
std::optional<toml::table> parse_toml_file(const std::string& path, ErrorList& errors);
std::optional<toml::table> parse_toml_text(std::string_view text, ErrorList& errors);

}  // namespace toonforce
