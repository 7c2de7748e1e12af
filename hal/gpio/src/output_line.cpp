// SPDX-License-Identifier: Apache-2.0
// One output line held on its own (output_line.hpp), through libgpiod 1.6.
#include "toonforce/hal/gpio/output_line.hpp"

#include <gpiod.h>

#include <cerrno>
#include <cstring>

#include <fmt/format.h>

namespace toonforce::gpio {

Result<std::unique_ptr<OutputLine>> OutputLine::open(const LineSpec& spec, const std::string& consumer) {
  gpiod_chip* chip = nullptr;
  gpiod_line* line = nullptr;
  std::string where;
  errno = 0;
  if (spec.by_name()) {
    line = gpiod_line_find(spec.name.c_str());  // opens the chip it is on
    if (line == nullptr) {
      return Error{fmt::format("{}: no GPIO line is named '{}'{} (`gpioinfo` lists the lines)", spec.text, spec.name,
                               errno != 0 && errno != ENOENT ? fmt::format(" ({})", std::strerror(errno)) : "")};
    }
    chip = gpiod_line_get_chip(line);
    where = fmt::format("{} line {} '{}'", gpiod_chip_name(chip), gpiod_line_offset(line), spec.name);
  } else {
    const std::string path = chip_path(spec.chip);
    chip = gpiod_chip_open(path.c_str());
    if (chip == nullptr) {
      const int error = errno;
      return Error{fmt::format(
          "{}: cannot open {}: {}{}", spec.text, path, std::strerror(error),
          error == EACCES ? " (the user needs read-write access to it: the gpio group, docs/GPIO.md)" : "")};
    }
    line = gpiod_chip_get_line(chip, spec.offset);
    if (line == nullptr) {
      const unsigned n = gpiod_chip_num_lines(chip);
      gpiod_chip_close(chip);
      return Error{fmt::format("{}: {} has lines 0..{}, not {}", spec.text, path, n == 0 ? 0 : n - 1, spec.offset)};
    }
    where = fmt::format("{} line {}", path, spec.offset);
  }
  const int flags = spec.active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  if (gpiod_line_request_output_flags(line, consumer.c_str(), flags, 0) != 0) {
    const int error = errno;
    const char* holder = gpiod_line_consumer(line);
    const std::string user = holder != nullptr ? holder : "";  // the line dies with the chip
    gpiod_chip_close(chip);
    return Error{fmt::format("{}: cannot take {} as an output: {}{}", spec.text, where, std::strerror(error),
                             error == EBUSY && !user.empty() ? fmt::format(" (held by '{}')", user) : "")};
  }
  std::unique_ptr<OutputLine> held(new OutputLine(chip, line, where));
  held->chip_node_ = fmt::format("/dev/{}", gpiod_chip_name(chip));
  held->offset_ = gpiod_line_offset(line);
  held->active_low_ = spec.active_low;
  return held;
}

OutputLine::~OutputLine() {
  if (chip_ == nullptr) return;  // close_copy()
  static_cast<void>(set(false));
  gpiod_chip_close(chip_);  // releases the line
}

void OutputLine::close_copy() noexcept {
  if (chip_ != nullptr) gpiod_chip_close(chip_);  // only close(2)s: no value is written
  chip_ = nullptr;
  line_ = nullptr;
}

bool OutputLine::set(bool active) noexcept {
  return line_ != nullptr && gpiod_line_set_value(line_, active ? 1 : 0) == 0;
}

}  // namespace toonforce::gpio
