// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Emulated GPIO chips for tests and benchmarks on hosts without GPIO: `/dev/gpiochip0..N-1`
/// speaking the GPIO character-device uAPI v1 that libgpiod 1.6 uses, served by umockdev
/// (libumockdev-preload redirects /dev and /sys and forwards ioctls to handlers that run on
/// umockdev's worker thread in this process; docs/GPIO.md, "The emulation"). Generalised to
/// several chips, named lines, active-low and bias, and injected faults.
///
/// Only works inside `umockdev-wrapper` (check `available()` first). The ioctl round trip
/// costs ~0.2 ms, so this proves behaviour, never timing. Not emulated: edge events.

#include <cerrno>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "toonforce/hal/gpio/line_spec.hpp"

namespace toonforce::gpio::emulation {

struct ChipSpec {
  std::string label = "toonforce-emulated";
  unsigned num_lines = 8;
  std::vector<std::string> line_names;  ///< by offset; missing or empty: unnamed
};

/// What the emulated kernel and the "hardware" know about one line.
struct LineState {
  bool requested = false;  ///< held by a line handle (of this process or a claim())
  bool output = false;
  bool active_low = false;  ///< requested active-low: values are inverted at the handle
  Bias bias = Bias::kAsIs;
  std::string consumer;       ///< the requester's label, as line info reports it
  int physical = 0;           ///< electrical level on the pin (0 low, 1 high)
  std::uint64_t writes = 0;   ///< GPIOHANDLE_SET_LINE_VALUES ioctls that included the line
  std::uint64_t reads = 0;    ///< GPIOHANDLE_GET_LINE_VALUES ioctls that included the line
  std::uint64_t changes = 0;  ///< physical level changes made by writes
};

class EmulatedGpio {
 public:
  /// True inside umockdev-wrapper (the preload library is active).
  static bool available() noexcept;

  /// Creates `/dev/gpiochip<i>` for each spec (major 254, minor i).
  explicit EmulatedGpio(const std::vector<ChipSpec>& chips);
  ~EmulatedGpio();
  EmulatedGpio(const EmulatedGpio&) = delete;
  EmulatedGpio& operator=(const EmulatedGpio&) = delete;

  // ---- the world around the chip -----------------------------------------------------------
  /// Something outside drives the pin to `level` (0 or 1): a switch, a sensor.
  void drive(unsigned chip, unsigned offset, int level);
  /// Nothing drives the pin any more (a broken wire, an unplugged switch): the requested pull
  /// resistor decides the level; without one it keeps its last level.
  void disconnect(unsigned chip, unsigned offset);
  /// A snapshot of the line.
  LineState line(unsigned chip, unsigned offset) const;
  /// Every ioctl the emulation answered (chips and line handles).
  std::uint64_t ioctl_count() const;

  // ---- faults ------------------------------------------------------------------------------
  /// Another program holds the line: line info reports `consumer`, a request fails EBUSY.
  void claim(unsigned chip, unsigned offset, std::string consumer);
  /// Opening the chip fails with `error` (EACCES: the node's mode does not let us in). The
  /// error is returned by the first ioctl libgpiod makes on open (GPIO_GET_CHIPINFO), as the
  /// preload cannot fail open() itself; libgpiod reports both the same way (NULL + errno).
  void deny_open(unsigned chip, int error = EACCES);
  /// The line-handle request fails with `error`, although line info shows the line free.
  void fail_request(unsigned chip, unsigned offset, int error);
  /// Value ioctls on handles holding the line fail with `error` (0 heals).
  void fail_values(unsigned chip, unsigned offset, int error = EIO);

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace toonforce::gpio::emulation
