// SPDX-License-Identifier: Apache-2.0
// Start-up: from the command-line strings to requested lines, or to messages a person can act
// on. Uses the libgpiod 1.6 C API (gpiod.h): one chip handle per chip, errno for each failure.
#include "toonforce/hal/gpio/gpio_session.hpp"

#include <dirent.h>
#include <grp.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <optional>
#include <utility>

#include <fmt/format.h>
#include <gpiod.h>

namespace toonforce::gpio {

void GpioSession::ChipCloser::operator()(gpiod_chip* chip) const noexcept {
  gpiod_chip_close(chip);  // releases every line requested through it
}
// A moved-from session owns no chip and must not touch the lines it used to name.
GpioSession::GpioSession(GpioSession&& other) noexcept
    : chips_(std::move(other.chips_)),
      pins_(std::exchange(other.pins_, GpioPins{})),
      summary_(std::move(other.summary_)) {}
GpioSession& GpioSession::operator=(GpioSession&& other) noexcept {
  if (this != &other) {
    close();
    chips_ = std::move(other.chips_);
    pins_ = std::exchange(other.pins_, GpioPins{});
    summary_ = std::move(other.summary_);
  }
  return *this;
}
GpioSession::~GpioSession() { close(); }

void GpioSession::close() noexcept {
  // The kernel leaves an output at its last level when the line is released: an "armed"
  // light must not stay lit after the run, so every light goes off first.
  if (!chips_.empty()) pins_.lights.all_off();
  pins_ = GpioPins{};
  chips_.clear();
}

namespace {

std::string chip_name(std::string_view path) {
  const auto slash = path.rfind('/');
  return std::string(slash == std::string_view::npos ? path : path.substr(slash + 1));
}

std::string errno_text(int error) { return std::strerror(error); }

/// /dev/gpiochipN paths in N order. opendir (not scandir, which libgpiod's chip iterator uses)
/// so that umockdev's redirection of /dev applies in tests too.
std::vector<std::string> chip_paths() {
  std::vector<std::pair<unsigned, std::string>> found;
  if (DIR* dir = opendir("/dev")) {
    while (const dirent* entry = readdir(dir)) {
      const std::string_view name = entry->d_name;
      if (!name.starts_with("gpiochip") || name.size() == 8) continue;
      const auto digits = name.substr(8);
      if (digits.find_first_not_of("0123456789") != std::string_view::npos) continue;
      unsigned number = 0;
      const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), number);
      if (ec != std::errc{} || end != digits.data() + digits.size()) continue;
      found.emplace_back(number, fmt::format("/dev/{}", name));
    }
    closedir(dir);
  }
  std::sort(found.begin(), found.end());
  std::vector<std::string> paths;
  paths.reserve(found.size());
  for (auto& [number, path] : found) paths.push_back(std::move(path));
  return paths;
}

std::string mode_text(mode_t mode) {
  std::string text = S_ISCHR(mode) ? "c" : "-";
  const char* rwx = "rwxrwxrwx";
  for (int bit = 8; bit >= 0; --bit) text += (mode & (1U << bit)) != 0 ? rwx[8 - bit] : '-';
  return text;
}

std::string group_name(gid_t gid) {
  std::vector<char> buffer(4096);
  group entry{};
  group* result = nullptr;
  if (getgrgid_r(gid, &entry, buffer.data(), buffer.size(), &result) == 0 && result != nullptr) {
    return result->gr_name;
  }
  return std::to_string(gid);
}

/// No permission on a chip node: which node, who may use it, and the fix.
std::string permission_problem(const std::string& path) {
  std::string text = fmt::format("no permission to open {}", path);
  struct stat st {};
  std::optional<std::string> group;
  if (stat(path.c_str(), &st) == 0) {
    group = group_name(st.st_gid);
    text += fmt::format(" (mode {}, group {})", mode_text(st.st_mode), *group);
  }
  if (group && st.st_gid != 0) {
    text += fmt::format(". Fix: add yourself to that group (sudo usermod -aG {0} $USER), then log out and in "
                        "again; check with: id | grep {0}",
                        *group);
  } else {
    text += ". Fix: let the group gpio use GPIO chips with a udev rule and join it: "
            "echo 'SUBSYSTEM==\"gpio\", KERNEL==\"gpiochip*\", GROUP=\"gpio\", MODE=\"0660\"' | "
            "sudo tee /etc/udev/rules.d/60-gpiochip.rules && sudo groupadd -f gpio && "
            "sudo usermod -aG gpio $USER && sudo udevadm control --reload && sudo udevadm trigger, "
            "then log out and in again";
  }
  return text;
}

std::string open_problem(const std::string& path, int error) {
  if (error == EACCES || error == EPERM) return permission_problem(path);
  if (error == ENOTTY || error == ENODEV) return fmt::format("{} is not a GPIO chip device", path);
  return fmt::format("cannot open {}: {}", path, errno_text(error));
}

/// The chips opened so far, each once; handed to the session at the end.
class ChipCache {
 public:
  struct Opened {
    gpiod_chip* chip = nullptr;
    int error = 0;
  };

  Opened open(const std::string& path) {
    for (const auto& e : entries_) {
      if (e.path == path) return {e.chip, e.error};
    }
    errno = 0;
    gpiod_chip* chip = gpiod_chip_open(path.c_str());
    const int error = chip == nullptr ? (errno != 0 ? errno : EIO) : 0;
    entries_.push_back({path, chip, error});
    return {chip, error};
  }

  ~ChipCache() {
    for (auto& e : entries_) {
      if (e.chip != nullptr) gpiod_chip_close(e.chip);
    }
  }

  /// Moves the open chips out (the session closes them).
  template <class Sink>
  void release_into(Sink&& sink) {
    for (auto& e : entries_) {
      if (e.chip != nullptr) sink(std::exchange(e.chip, nullptr));
    }
  }

 private:
  struct Entry {
    std::string path;
    gpiod_chip* chip;
    int error;
  };
  std::vector<Entry> entries_;
};

std::string describe_chips(ChipCache& cache) {
  const auto paths = chip_paths();
  if (paths.empty()) {
    return "this host has no GPIO chips (no /dev/gpiochip*): is the GPIO driver loaded, and the "
           "kernel built with CONFIG_GPIO_CDEV?";
  }
  std::string text = "the chips here are";
  const char* sep = " ";
  for (const auto& path : paths) {
    const auto opened = cache.open(path);
    if (opened.chip != nullptr) {
      text += fmt::format("{}{} [{}, {} lines]", sep, chip_name(path), gpiod_chip_label(opened.chip),
                          gpiod_chip_num_lines(opened.chip));
    } else {
      text += fmt::format("{}{} [cannot open: {}]", sep, chip_name(path), errno_text(opened.error));
    }
    sep = ", ";
  }
  return text;
}

/// Lines by name on every chip, built on first use (one line-info ioctl per line).
class NameIndex {
 public:
  struct Place {
    std::string path;
    unsigned offset;
  };

  void build(ChipCache& cache) {
    if (built_) return;
    built_ = true;
    for (const auto& path : chip_paths()) {
      searched_.push_back(chip_name(path));
      const auto opened = cache.open(path);
      if (opened.chip == nullptr) {
        unsearched_.push_back(fmt::format("{} ({})", chip_name(path), open_problem(path, opened.error)));
        continue;
      }
      const unsigned n = gpiod_chip_num_lines(opened.chip);
      for (unsigned offset = 0; offset < n; ++offset) {
        gpiod_line* line = gpiod_chip_get_line(opened.chip, offset);
        const char* name = line != nullptr ? gpiod_line_name(line) : nullptr;
        if (name != nullptr) lines_.push_back({name, {path, offset}});
      }
    }
  }

  std::vector<Place> find(std::string_view name) const {
    std::vector<Place> places;
    for (const auto& [line_name, place] : lines_) {
      if (line_name == name) places.push_back(place);
    }
    return places;
  }
  const std::vector<std::string>& searched() const { return searched_; }
  const std::vector<std::string>& unsearched() const { return unsearched_; }

 private:
  bool built_ = false;
  std::vector<std::pair<std::string, Place>> lines_;
  std::vector<std::string> searched_;
  std::vector<std::string> unsearched_;
};

enum class Role { kTick, kEstop, kEnable, kLight };

/// One pin to open.
struct Wanted {
  Role role;
  LightState light = LightState::kIdle;  // kLight only
  std::string option;                    // "--estop-pin ESTOP:active-low", for messages
  std::string what;                      // "e-stop", "armed light"
  LineSpec spec;
  std::string path;  // resolved chip
  unsigned offset = 0;
  gpiod_line* line = nullptr;

  bool output() const { return role == Role::kTick || role == Role::kLight; }
};

std::string join(const std::vector<std::string>& parts, std::string_view sep) {
  std::string text;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (i != 0) text += sep;
    text += parts[i];
  }
  return text;
}

/// Finds the chip and offset of a line named by name; nullopt after recording the problem.
std::optional<std::string> resolve_by_name(Wanted& w, ChipCache& cache, NameIndex& index) {
  index.build(cache);
  const auto places = index.find(w.spec.name);
  if (places.size() == 1) {
    w.path = places[0].path;
    w.offset = places[0].offset;
    return std::nullopt;
  }
  if (places.size() > 1) {
    std::vector<std::string> where;
    where.reserve(places.size());
    for (const auto& p : places) where.push_back(fmt::format("{}:{}", chip_name(p.path), p.offset));
    return fmt::format("the name '{}' belongs to several lines ({}); name the line as CHIP:OFFSET", w.spec.name,
                       join(where, ", "));
  }
  std::string text;
  if (index.searched().empty()) {
    text = fmt::format("no line named '{}': {}", w.spec.name, describe_chips(cache));
  } else {
    text = fmt::format("no line named '{}' on any GPIO chip (searched {}; `gpioinfo` lists the "
                       "line names)",
                       w.spec.name, join(index.searched(), ", "));
  }
  if (!index.unsearched().empty()) {
    text += fmt::format("; could not search {}", join(index.unsearched(), "; "));
  }
  return text;
}

std::string in_use_problem(const Wanted& w, gpiod_line* line) {
  const char* consumer = gpiod_line_consumer(line);
  return fmt::format("{}:{} is in use by {}; stop that program or release the line (`gpioinfo {}` shows who "
                     "holds each line), or choose another line",
                     chip_name(w.path), w.offset,
                     consumer != nullptr ? fmt::format("'{}'", consumer) : std::string("another user (no label)"),
                     chip_name(w.path));
}

/// Opens the chip, checks the offset and requests the line; the problem if any.
std::optional<std::string> request(Wanted& w, ChipCache& cache, std::string_view consumer) {
  const auto opened = cache.open(w.path);
  if (opened.chip == nullptr) {
    if (opened.error == ENOENT) {
      return fmt::format("no GPIO chip {}; {}", w.path, describe_chips(cache));
    }
    return open_problem(w.path, opened.error);
  }
  const unsigned n = gpiod_chip_num_lines(opened.chip);
  if (w.offset >= n) {
    return fmt::format("{} has {} lines (offsets 0 to {}); there is no line {}", chip_name(w.path), n, n - 1, w.offset);
  }
  errno = 0;
  gpiod_line* line = gpiod_chip_get_line(opened.chip, w.offset);
  if (line == nullptr) {
    return fmt::format("cannot read the line info of {}:{}: {}", chip_name(w.path), w.offset, errno_text(errno));
  }
  if (gpiod_line_is_used(line)) return in_use_problem(w, line);

  int flags = 0;
  if (w.spec.active_low) flags |= GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW;
  if (w.spec.bias == Bias::kPullUp) flags |= GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_UP;
  if (w.spec.bias == Bias::kPullDown) flags |= GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_DOWN;
  const std::string label(consumer);
  const gpiod_line_request_config config{
      label.c_str(), w.output() ? GPIOD_LINE_REQUEST_DIRECTION_OUTPUT : GPIOD_LINE_REQUEST_DIRECTION_INPUT, flags};
  errno = 0;
  if (gpiod_line_request(line, &config, 0) != 0) {  // outputs start at 0: tick low, LEDs off
    const int error = errno;
    if (error == EBUSY) {
      gpiod_line_update(line);  // someone took it since the check: say who
      return in_use_problem(w, line);
    }
    if (error == EACCES || error == EPERM) return permission_problem(w.path);
    if (error == EINVAL && w.spec.bias != Bias::kAsIs) {
      return fmt::format("{}:{}: the kernel refused the pull resistor ({}); bias needs Linux 5.5 "
                         "or later and a chip that supports it; wire an external resistor instead",
                         chip_name(w.path), w.offset, errno_text(error));
    }
    return fmt::format("cannot request {}:{}: {}", chip_name(w.path), w.offset, errno_text(error));
  }
  w.line = line;

  if (!w.output()) {
    // One read now, so a line that cannot be read stops the start, not the first tick.
    errno = 0;
    if (gpiod_line_get_value(line) < 0) {
      return fmt::format("cannot read {}:{}: {}", chip_name(w.path), w.offset, errno_text(errno));
    }
  }
  return std::nullopt;
}

std::string summary_line(const Wanted& w) {
  std::string text = fmt::format("{:<14} {}:{}", w.what, chip_name(w.path), w.offset);
  if (const char* name = gpiod_line_name(w.line)) text += fmt::format(" '{}'", name);
  text += w.output() ? " output" : " input";
  if (w.spec.active_low) text += ", active-low";
  if (w.spec.bias == Bias::kPullUp) text += ", pull-up";
  if (w.spec.bias == Bias::kPullDown) text += ", pull-down";
  return text;
}

}  // namespace

Result<GpioSession> open_gpio(const GpioOptions& options, std::string_view consumer) {
  std::vector<std::string> problems;
  std::vector<Wanted> wanted;

  auto add_line = [&](Role role, std::string_view option, std::string_view what, const std::string& text) {
    if (text.empty()) return;
    const std::string label = fmt::format("{} {}", option, text);
    auto spec = parse_line_spec(text);
    if (!spec) {
      problems.push_back(fmt::format("{}: {}", option, spec.error()));
      return;
    }
    wanted.push_back(
        Wanted{role, LightState::kIdle, label, std::string(what), std::move(spec).value(), {}, 0, nullptr});
  };
  add_line(Role::kTick, "--tick-pin", "tick pin", options.tick_pin);
  add_line(Role::kEstop, "--estop-pin", "e-stop", options.estop_pin);
  add_line(Role::kEnable, "--enable-pin", "enable", options.enable_pin);
  std::vector<bool> light_given(GpioLights::kStates, false);
  for (const auto& text : options.led_pins) {
    auto led = parse_led_spec(text);
    if (!led) {
      problems.push_back(fmt::format("--led-pin: {}", led.error()));
      continue;
    }
    const auto index = static_cast<std::size_t>(led->state);
    if (light_given[index]) {
      problems.push_back(fmt::format("--led-pin {}: the {} light is given twice", text, light_state_name(led->state)));
      continue;
    }
    light_given[index] = true;
    wanted.push_back(Wanted{Role::kLight,
                            led->state,
                            fmt::format("--led-pin {}", text),
                            fmt::format("{} light", light_state_name(led->state)),
                            led->line,
                            {},
                            0,
                            nullptr});
  }

  ChipCache cache;
  NameIndex names;
  std::vector<bool> resolved(wanted.size(), false);
  for (std::size_t i = 0; i < wanted.size(); ++i) {
    Wanted& w = wanted[i];
    if (w.spec.by_name()) {
      if (auto problem = resolve_by_name(w, cache, names)) {
        problems.push_back(fmt::format("{}: {}", w.option, *problem));
        continue;
      }
    } else {
      w.path = chip_path(w.spec.chip);
      w.offset = w.spec.offset;
    }
    // Two options on one line would fight over it (and the kernel refuses the second).
    bool duplicate = false;
    for (std::size_t j = 0; j < i; ++j) {
      if (resolved[j] && wanted[j].path == w.path && wanted[j].offset == w.offset) {
        problems.push_back(fmt::format("{}: {}:{} is already the line of {}; each pin needs its own line", w.option,
                                       chip_name(w.path), w.offset, wanted[j].option));
        duplicate = true;
        break;
      }
    }
    if (!duplicate) resolved[i] = true;
  }

  for (std::size_t i = 0; i < wanted.size(); ++i) {
    if (!resolved[i]) continue;
    if (auto problem = request(wanted[i], cache, consumer)) {
      problems.push_back(fmt::format("{}: {}", wanted[i].option, *problem));
    }
  }
  if (!problems.empty()) return Error{join(problems, "\n")};  // ~ChipCache releases all lines

  GpioSession session;
  for (const auto& w : wanted) {
    switch (w.role) {
      case Role::kTick: session.pins_.tick = GpioTickPin(w.line, 0); break;
      case Role::kEstop: session.pins_.estop = GpioEstopPin(w.line); break;
      case Role::kEnable: session.pins_.enable = GpioEnablePin(w.line); break;
      case Role::kLight: session.pins_.lights.attach(w.light, w.line); break;
    }
    session.summary_.push_back(summary_line(w));
  }
  cache.release_into([&](gpiod_chip* chip) { session.chips_.emplace_back(chip); });
  return session;
}

std::vector<ChipInfo> list_chips() {
  std::vector<ChipInfo> chips;
  for (const auto& path : chip_paths()) {
    ChipInfo info;
    info.path = path;
    errno = 0;
    if (gpiod_chip* chip = gpiod_chip_open(path.c_str())) {
      info.label = gpiod_chip_label(chip);
      info.num_lines = gpiod_chip_num_lines(chip);
      gpiod_chip_close(chip);
    } else {
      info.problem = open_problem(path, errno != 0 ? errno : EIO);
    }
    chips.push_back(std::move(info));
  }
  return chips;
}

std::string pin_error_summary(const GpioPins& pins) {
  std::vector<std::string> parts;
  if (pins.tick.write_errors() != 0)
    parts.push_back(fmt::format("tick pin: {} failed writes", pins.tick.write_errors()));
  if (pins.estop.read_errors() != 0) parts.push_back(fmt::format("e-stop: {} failed reads", pins.estop.read_errors()));
  if (pins.enable.read_errors() != 0)
    parts.push_back(fmt::format("enable: {} failed reads", pins.enable.read_errors()));
  if (pins.lights.write_errors() != 0)
    parts.push_back(fmt::format("lights: {} failed updates", pins.lights.write_errors()));
  return join(parts, ", ");
}

}  // namespace toonforce::gpio
