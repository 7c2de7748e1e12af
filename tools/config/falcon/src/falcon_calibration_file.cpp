// SPDX-License-Identifier: Apache-2.0
// The Falcon's calibration file (falcon_calibration_file.hpp), read with TableReader so its errors
// look like a scene file's.
#include "toonforce/config/falcon_calibration_file.hpp"

#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "toonforce/config/toml_reader.hpp"

namespace toonforce::falcon {
namespace {

constexpr std::string_view kMethods[] = {"weight", "spring-scale", "manual"};

Result<FalconCalibration> describe(const toml::table& root, ErrorList& errors) {
  FalconCalibration c;
  TableReader r(root, "", errors, ScalarKind::kDouble);
  c.serial = r.optional_string("serial").value_or("");
  if (const auto k = r.required_number("words_per_newton_metre", Range::kPositive, "[word / (N m)]")) {
    if (*k < kMinWordsPerNewtonMetre || *k > kMaxWordsPerNewtonMetre) {
      r.error(
          "words_per_newton_metre",
          fmt::format("{} is outside {:.0f}..{:.0f} (libnifalcon uses {:.0f}; Novint's own driver about 2500-5000): "
                      "measure it again (docs/FALCON.md, \"Calibration\")",
                      *k, kMinWordsPerNewtonMetre, kMaxWordsPerNewtonMetre, kUncalibratedWordsPerNewtonMetre));
    } else {
      c.words_per_n_m = *k;
    }
  }
  if (const toml::table* m = r.optional_table("measurement")) {
    TableReader mr(*m, "measurement", errors, ScalarKind::kDouble);
    if (auto method = mr.optional_string("method")) {
      bool known = false;
      for (const auto k : kMethods) known = known || *method == k;
      if (!known) {
        mr.error("method", fmt::format("'{}' is not one of weight, spring-scale, manual", *method));
      } else {
        c.method = *method;
      }
    }
    c.reference_force_n = mr.optional_number("reference_force_n", Range::kPositive);
    c.measured_force_n = mr.optional_number("measured_force_n", Range::kPositive);
    c.date = mr.optional_string("date").value_or("");
    c.note = mr.optional_string("note", TableReader::StringKind::kText).value_or("");
    mr.finish();
  }
  r.finish();
  if (!errors.empty()) return Error{errors.text()};
  return c;
}

/// TOML basic string: quotes and backslashes escaped, control characters as \uXXXX.
std::string toml_string(std::string_view s) {
  std::string out = "\"";
  for (const char ch : s) {
    const auto u = static_cast<unsigned char>(ch);
    if (ch == '"' || ch == '\\') {
      out += '\\';
      out += ch;
    } else if (u < 0x20 || u == 0x7F) {
      out += fmt::format("\\u{:04X}", u);
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

}  // namespace

Result<FalconCalibration> parse_falcon_calibration(std::string_view text, const std::string& source) {
  ErrorList errors(source);
  const auto root = parse_toml_text(text, errors);
  if (!root) return Error{errors.text()};
  return describe(*root, errors);
}

Result<FalconCalibration> read_falcon_calibration(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return Error{fmt::format("{}: no such Falcon calibration file{} (`toonforce bringup falcon` writes one; "
                             "docs/FALCON.md, \"Calibration\")\n",
                             path, std::filesystem::exists(path, ec) ? " (it is not a regular file)" : "")};
  }
  ErrorList errors(path);
  const auto root = parse_toml_file(path, errors);
  if (!root) return Error{errors.text()};
  return describe(*root, errors);
}

std::string format_falcon_calibration(const FalconCalibration& c) {
  std::string out = "# toonforce Falcon calibration: the motor words per newton-metre of joint torque measured on\n"
                    "# this Falcon (docs/FALCON.md, \"Calibration\"). Written by `toonforce bringup falcon`.\n";
  if (!c.serial.empty()) out += fmt::format("serial = {}\n", toml_string(c.serial));
  // Enough digits to read back the same double.
  out += fmt::format("words_per_newton_metre = {:.17g}\n", c.words_per_n_m);
  const bool has_measurement =
      !c.method.empty() || c.reference_force_n || c.measured_force_n || !c.date.empty() || !c.note.empty();
  if (has_measurement) {
    out += "\n[measurement]\n";
    if (!c.method.empty()) out += fmt::format("method = {}\n", toml_string(c.method));
    if (c.reference_force_n) out += fmt::format("reference_force_n = {:.17g}\n", *c.reference_force_n);
    if (c.measured_force_n) out += fmt::format("measured_force_n = {:.17g}\n", *c.measured_force_n);
    if (!c.date.empty()) out += fmt::format("date = {}\n", toml_string(c.date));
    if (!c.note.empty()) out += fmt::format("note = {}\n", toml_string(c.note));
  }
  return out;
}

Result<std::string> write_falcon_calibration(const std::string& path, const FalconCalibration& c) {
  std::error_code ec;
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  if (!dir.empty()) std::filesystem::create_directories(dir, ec);
  if (ec) return Error{fmt::format("{}: cannot create the directory ({})", dir.string(), ec.message())};
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  const std::string text = format_falcon_calibration(c);
  out << text;
  out.close();
  if (!out) return Error{fmt::format("{}: cannot write the Falcon calibration file", path)};
  return path;
}

}  // namespace toonforce::falcon
