// SPDX-License-Identifier: Apache-2.0
// Numeric option checks shared by every subcommand (commands.hpp says why they replace CLI11's).
#include <sys/stat.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <string>

#include <fmt/format.h>

#include "commands.hpp"
#include "toonforce/sim/sim_run.hpp"

namespace toonforce::cli {

namespace {

/// "" when `text` is a finite number in [lo, hi], else what is wrong with it, in one line.
std::string check_number(const std::string& text, double lo, double hi, const char* wanted) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end == nullptr || *end != '\0') return fmt::format("'{}' is not a number", text);
  if (!std::isfinite(v) || errno == ERANGE) return fmt::format("{} is not a finite number ({})", text, wanted);
  if (v < lo || v > hi) return fmt::format("{} is outside {}", text, wanted);
  return {};
}

}  // namespace

CLI::Validator number_in(double lo, double hi) {
  const std::string wanted = fmt::format("{:g} .. {:g}", lo, hi);
  return CLI::Validator([lo, hi, wanted](std::string& text) { return check_number(text, lo, hi, wanted.c_str()); },
                        fmt::format("NUMBER in {}", wanted));
}

CLI::Validator positive_number() {
  return CLI::Validator(
      [](std::string& text) {
        std::string bad = check_number(text, 0.0, std::numeric_limits<double>::max(), "a positive number");
        if (bad.empty() && std::strtod(text.c_str(), nullptr) <= 0.0) bad = fmt::format("{} is not positive", text);
        return bad;
      },
      "POSITIVE");
}

CLI::Validator non_negative_number() {
  return CLI::Validator(
      [](std::string& text) { return check_number(text, 0.0, std::numeric_limits<double>::max(), "a number >= 0"); },
      "NON-NEGATIVE");
}

CLI::Validator max_output_range() {
  return CLI::Validator(
      [](std::string& text) {
        // AsSizeValue has turned "500M" into bytes; a sign or a value past 4 EiB is refused.
        if (text.find('-') != std::string::npos) return fmt::format("{} is negative (bytes, 0 .. 4E)", text);
        return check_number(text, 0.0, 4.0 * 1152921504606846976.0, "0 .. 4E bytes");
      },
      "SIZE");
}

std::string input_overwritten_by(const std::string& output, std::initializer_list<std::string> inputs) {
  if (output.empty() || output == "-") return {};
  struct stat out {};
  const bool exists = ::stat(output.c_str(), &out) == 0;
  std::error_code ec;
  const std::filesystem::path out_name = std::filesystem::weakly_canonical(output, ec);
  for (const std::string& input : inputs) {
    if (input.empty() || input == "-") continue;
    struct stat in {};
    if (exists) {
      if (::stat(input.c_str(), &in) == 0 && in.st_dev == out.st_dev && in.st_ino == out.st_ino) return input;
    } else {
      std::error_code in_ec;
      if (!ec && std::filesystem::weakly_canonical(input, in_ec) == out_name && !in_ec) return input;
    }
  }
  return {};
}

}  // namespace toonforce::cli
