// SPDX-License-Identifier: Apache-2.0
#pragma once
/// One output line held on its own, outside any GPIO session: `toonforce run`'s guardian holds
/// the amplifier-enable line with it (--amp-enable-pin; tools/run/guardian.hpp), active only
/// while the loop ticks, so that the loop's process cannot keep the amplifier on after its end.
/// Requested as an output at its inactive level (active-low honoured by the kernel).

#include <memory>
#include <string>

#include "toonforce/common/result.hpp"
#include "toonforce/hal/gpio/line_spec.hpp"

struct gpiod_chip;
struct gpiod_line;

namespace toonforce::gpio {

class OutputLine {
 public:
  /// Opens `spec` (CHIP:OFFSET or a name) as an output at its inactive level, labelled
  /// `consumer`. The error names the line, the chip and what to do.
  static Result<std::unique_ptr<OutputLine>> open(const LineSpec& spec, const std::string& consumer);
  ~OutputLine();
  OutputLine(const OutputLine&) = delete;
  OutputLine& operator=(const OutputLine&) = delete;

  /// Drives the line active or inactive: one ioctl. False on failure.
  bool set(bool active) noexcept;
  const std::string& describe() const noexcept { return description_; }
  /// Where the line is: its chip's node (/dev/gpiochipN) and offset, and whether it is active
  /// low (`toonforce run` hands these to its guardian, which requests the line itself).
  const std::string& chip_node() const noexcept { return chip_node_; }
  unsigned offset() const noexcept { return offset_; }
  bool active_low() const noexcept { return active_low_; }
  /// Closes this process's descriptors without driving the line: a forked child's copy (the
  /// line stays requested, at its level, by the process that keeps its own).
  void close_copy() noexcept;

 private:
  OutputLine(gpiod_chip* chip, gpiod_line* line, std::string description) noexcept
      : chip_(chip), line_(line), description_(std::move(description)) {}
  gpiod_chip* chip_;
  gpiod_line* line_;
  std::string description_;
  std::string chip_node_;
  unsigned offset_ = 0;
  bool active_low_ = false;
};

}  // namespace toonforce::gpio
