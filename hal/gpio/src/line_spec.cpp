// SPDX-License-Identifier: Apache-2.0
#include "toonforce/hal/gpio/line_spec.hpp"

#include <array>
#include <charconv>

#include <fmt/format.h>

namespace toonforce::gpio {
namespace {

constexpr std::string_view kLineForm = "expected CHIP:OFFSET[:FLAG...] (e.g. gpiochip0:17:active-low) "
                                       "or LINE_NAME[:FLAG...]; FLAG is active-low, pull-up or pull-down";

std::vector<std::string_view> split(std::string_view text, char sep) {
  std::vector<std::string_view> parts;
  for (;;) {
    const auto at = text.find(sep);
    parts.push_back(text.substr(0, at));
    if (at == std::string_view::npos) return parts;
    text.remove_prefix(at + 1);
  }
}

std::optional<unsigned> parse_unsigned(std::string_view digits) {
  if (digits.empty() || digits.find_first_not_of("0123456789") != std::string_view::npos) {
    return std::nullopt;
  }
  unsigned value = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
  if (ec != std::errc{} || end != digits.data() + digits.size()) return std::nullopt;
  return value;
}

bool is_chip(std::string_view field) {
  if (field.starts_with("/dev/")) return true;
  if (field.starts_with("gpiochip")) return parse_unsigned(field.substr(8)).has_value();
  return parse_unsigned(field).has_value();
}

}  // namespace

Result<LineSpec> parse_line_spec(std::string_view text) {
  LineSpec spec;
  spec.text = std::string(text);
  if (text.empty()) return Error{fmt::format("empty line; {}", kLineForm)};
  const auto fields = split(text, ':');

  std::size_t flags_from = 1;
  if (fields.size() >= 2 && is_chip(fields[0]) && !fields[1].empty() &&
      fields[1].find_first_not_of("0123456789") == std::string_view::npos) {
    const auto offset = parse_unsigned(fields[1]);
    if (!offset) return Error{fmt::format("'{}': line offset {} is too large", text, fields[1])};
    spec.chip = std::string(fields[0]);
    spec.offset = *offset;
    flags_from = 2;
  } else if (is_chip(fields[0])) {
    // "gpiochip0" or "gpiochip0:x": a chip without a valid offset, not a line name.
    const std::string_view got = fields.size() >= 2 ? fields[1] : std::string_view{};
    return Error{got.empty() ? fmt::format("'{}': no line offset after the chip; {}", text, kLineForm)
                             : fmt::format("'{}': line offset '{}' is not a number; {}", text, got, kLineForm)};
  } else {
    if (fields[0].empty()) return Error{fmt::format("'{}': no line name; {}", text, kLineForm)};
    spec.name = std::string(fields[0]);
  }

  bool bias_set = false;
  for (std::size_t i = flags_from; i < fields.size(); ++i) {
    const std::string_view flag = fields[i];
    if (flag == "active-low") {
      if (spec.active_low) return Error{fmt::format("'{}': active-low given twice", text)};
      spec.active_low = true;
    } else if (flag == "pull-up" || flag == "pull-down") {
      if (bias_set) return Error{fmt::format("'{}': give at most one of pull-up, pull-down", text)};
      spec.bias = flag == "pull-up" ? Bias::kPullUp : Bias::kPullDown;
      bias_set = true;
    } else {
      return Error{fmt::format("'{}': unknown flag '{}'; {}", text, flag, kLineForm)};
    }
  }
  return spec;
}

std::string_view light_state_name(LightState state) noexcept {
  switch (state) {
    case LightState::kIdle: return "idle";
    case LightState::kHoming: return "homing";
    case LightState::kArmed: return "armed";
    case LightState::kFault: return "fault";
  }
  return "?";
}

std::optional<LightState> parse_light_state(std::string_view name) noexcept {
  for (const auto s : {LightState::kIdle, LightState::kHoming, LightState::kArmed, LightState::kFault}) {
    if (name == light_state_name(s)) return s;
  }
  return std::nullopt;
}

Result<LedSpec> parse_led_spec(std::string_view text) {
  const auto eq = text.find('=');
  if (eq == std::string_view::npos) {
    return Error{fmt::format("'{}': expected ROLE=LINE with ROLE one of idle, homing, armed, fault "
                             "(e.g. armed=gpiochip0:5)",
                             text)};
  }
  const auto role = text.substr(0, eq);
  const auto state = parse_light_state(role);
  if (!state) {
    return Error{fmt::format("'{}': unknown light '{}'; the lights are idle, homing, armed, fault", text, role)};
  }
  auto line = parse_line_spec(text.substr(eq + 1));
  if (!line) return Error{fmt::format("{} light: {}", role, line.error())};
  return LedSpec{*state, std::move(line).value()};
}

std::string chip_path(std::string_view chip) {
  if (chip.starts_with("/")) return std::string(chip);
  if (parse_unsigned(chip)) return fmt::format("/dev/gpiochip{}", chip);
  return fmt::format("/dev/{}", chip);
}

}  // namespace toonforce::gpio
