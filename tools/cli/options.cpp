// SPDX-License-Identifier: Apache-2.0
// Numeric option checks shared by every subcommand (commands.hpp says why they replace CLI11's),
// and the parse and exit status that toonforce and the lab's toonforce-lab share.
#include <sys/stat.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <limits>
#include <new>
#include <string>
#include <system_error>

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

namespace {
int g_exit_code = 0;
}

int exit_code() { return g_exit_code; }
void set_exit_code(int code) { g_exit_code = code; }

int parse_and_finish(CLI::App& app, int argc, char** argv, const char* program) {
  int code = 0;
  try {
    app.parse(argc, argv);
    code = exit_code();
  } catch (const CLI::ParseError& e) {
    // A bad command line (unknown flag, missing or out-of-range value) is "cannot start": 2
    // (interfaces.md), not CLI11's own codes (105, 106, 109, ...); --help and --version are 0.
    code = app.exit(e) == 0 ? 0 : 2;
  } catch (const std::bad_alloc&) {
    // Too little memory (`ulimit -v`): cannot start (interfaces.md, exits.md), said in one line.
    std::fputs(program, stderr);  // no formatting: nothing more to allocate
    std::fputs(": out of memory (is `ulimit -v` too small?)\n", stderr);
    code = 2;
  } catch (const std::system_error& e) {
    if (e.code() == std::errc::resource_unavailable_try_again || e.code() == std::errc::not_enough_memory) {
      // A thread or a mapping refused (`ulimit -v`): cannot start, as above.
      std::fprintf(stderr, "%s: %s (too little memory: is `ulimit -v` too small?)\n", program, e.what());
      code = 2;
    } else {
      // A message that could not be written (standard error a closed pipe, a full disk): the
      // run itself ended as it would have; what could not be said is a failed status (exits.md).
      std::fprintf(stderr, "%s: %s\n", program, e.what());
      code = 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", program, e.what());
    code = 1;
  }
  // What went to standard output must have arrived (`falcon udev-rule > /dev/full`).
  if (std::fflush(stdout) != 0 || std::ferror(stdout) != 0) {
    std::fprintf(stderr, "%s: writing to standard output failed\n", program);
    if (code == 0) code = 1;
  }
  return code;
}

}  // namespace toonforce::cli
