// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Opening the GPIO lines of a run, once, before the servo loop starts: parse the command-line
/// strings, find each line (by chip and offset, or by name on every chip), and request it from
/// the kernel with the consumer label "toonforce". Everything that can go wrong is reported
/// here, all problems at once, each naming the option, the line, and what to do: a missing
/// chip (with the chips that exist), a line out of range, a line in use (and by whom), no
/// permission (which device node, and the group or udev rule that fixes it). Start-up code: it
/// allocates and may take milliseconds; nothing here runs in a tick.

#include <memory>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/hal/pins.hpp"
#include "toonforce/hal/gpio/gpio_pins.hpp"
#include "toonforce/hal/gpio/line_spec.hpp"

struct gpiod_chip;

namespace toonforce::gpio {

/// The consumer label our lines carry (`gpioinfo` shows it).
inline constexpr std::string_view kConsumer = "toonforce";

class GpioSession;

/// Opens every configured pin, or returns every problem (one per line of the error text).
/// Options that are empty stay absent in the pins.
Result<GpioSession> open_gpio(const GpioOptions& options, std::string_view consumer = kConsumer);

/// The chips and requested lines of one run. Keep it alive while any copy of its pins is in
/// use. Closing it switches every light off and releases the lines (the kernel leaves an
/// output at its last level, so the tick pin stays where it was).
class GpioSession {
 public:
  GpioSession(GpioSession&&) noexcept;
  GpioSession& operator=(GpioSession&&) noexcept;
  ~GpioSession();

  /// The pins to hand to the servo loop (copy them; unconfigured ones are absent).
  const GpioPins& pins() const noexcept { return pins_; }
  /// One line per opened pin, for the start-up log, e.g.
  /// "e-stop   gpiochip0:4 'ESTOP' input, active-low, pull-down".
  const std::vector<std::string>& summary() const noexcept { return summary_; }

 private:
  struct ChipCloser {
    void operator()(gpiod_chip* chip) const noexcept;
  };
  GpioSession() = default;
  void close() noexcept;
  friend Result<GpioSession> open_gpio(const GpioOptions& options, std::string_view consumer);

  std::vector<std::unique_ptr<gpiod_chip, ChipCloser>> chips_;
  GpioPins pins_;
  std::vector<std::string> summary_;
};

/// A GPIO chip on this host, for messages (and for a `devices` listing).
struct ChipInfo {
  std::string path;   ///< "/dev/gpiochip0"
  std::string label;  ///< "pinctrl-bcm2711"; empty if the chip could not be opened
  unsigned num_lines = 0;
  std::string problem;  ///< why it could not be opened (empty when it could)
};
/// The chips under /dev (gpiochipN, in N order).
std::vector<ChipInfo> list_chips();

/// Read/write errors the pins counted during a run ("" when none), for the run summary.
std::string pin_error_summary(const GpioPins& pins);

/// Runs `run(pins)` with the pins the options ask for, choosing the loop's pin type at run
/// time without #ifdef: with no GPIO option, `run` gets `NullPins` (that instantiation contains
/// no GPIO code at all); otherwise it gets `GpioPins` from a session that stays open until
/// `run` returns. `run` is called with both types (a generic lambda), and must return the same
/// non-void type for both. If opening fails, `run` is not called and the error is returned.
template <class Run>
auto with_gpio_pins(const GpioOptions& options, Run&& run) -> Result<std::invoke_result_t<Run&, NullPins&>> {
  using R = std::invoke_result_t<Run&, NullPins&>;
  static_assert(std::is_same_v<R, std::invoke_result_t<Run&, GpioPins&>>,
                "run(NullPins&) and run(GpioPins&) must return the same type");
  if (options.empty()) {
    NullPins pins;
    return run(pins);
  }
  auto session = open_gpio(options);
  if (!session) return Error{session.error()};
  GpioPins pins = session->pins();
  return run(pins);
}

}  // namespace toonforce::gpio
