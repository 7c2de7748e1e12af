// SPDX-License-Identifier: Apache-2.0
// The person at the device (see operator.hpp).
#include "toonforce/bringup/operator.hpp"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>

#include <fmt/format.h>

namespace toonforce::bringup {

std::optional<bool> parse_yes_no(std::string_view text) {
  std::string t;
  for (const char c : text) {
    if (!std::isspace(static_cast<unsigned char>(c)))
      t += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  if (t == "y" || t == "yes" || t == "true" || t == "1") return true;
  if (t == "n" || t == "no" || t == "false" || t == "0") return false;
  return std::nullopt;
}

ConsoleOperator::ConsoleOperator(std::FILE* in, std::FILE* out, std::map<std::string, std::string> answers)
    : in_(in), out_(out), answers_(std::move(answers)) {}

void ConsoleOperator::say(std::string_view line) {
  fmt::print(out_, "{}\n", line);
  std::fflush(out_);
}

void ConsoleOperator::begin(const Request& request) {
  pending_.clear();
  if (answers_.count(request.id) != 0) return;
  fmt::print(out_, "\n>>> {}\n    (Enter when done, q to stop)\n", request.text);
  std::fflush(out_);
}

Progress ConsoleOperator::poll(const Request& request) {
  if (auto it = answers_.find(request.id); it != answers_.end()) {
    return it->second == "abort" ? Progress::kAbort : Progress::kDone;
  }
  // Reads whatever has been typed without waiting: the device keeps running meanwhile.
  const int fd = ::fileno(in_);
  pollfd p{fd, POLLIN, 0};
  while (::poll(&p, 1, 0) > 0 && (p.revents & (POLLIN | POLLHUP)) != 0) {
    char c = 0;
    if (::read(fd, &c, 1) != 1) return Progress::kAbort;  // end of input: nobody is there
    if (c != '\n') {
      pending_ += c;
      continue;
    }
    const std::string line = pending_;
    pending_.clear();
    if (line == "q" || line == "quit") return Progress::kAbort;
    return Progress::kDone;
  }
  return Progress::kWaiting;
}

std::optional<std::string> ConsoleOperator::ask(const Request& request) {
  if (auto it = answers_.find(request.id); it != answers_.end()) return it->second;
  fmt::print(out_, "\n??? {} ", request.text);
  std::fflush(out_);
  std::string line = pending_;
  pending_.clear();
  const int fd = ::fileno(in_);
  char c = 0;
  while (true) {
    const auto n = ::read(fd, &c, 1);
    if (n != 1) return std::nullopt;  // end of input
    if (c == '\n') break;
    line += c;
  }
  return line;
}

ScriptedOperator::ScriptedOperator(std::map<std::string, std::string> answers, std::FILE* out)
    : answers_(std::move(answers)), out_(out) {}

void ScriptedOperator::say(std::string_view line) {
  if (out_ == nullptr) return;
  fmt::print(out_, "{}\n", line);
  std::fflush(out_);
}

void ScriptedOperator::begin(const Request& request) {
  if (out_ != nullptr && answers_.count(request.id) == 0) {
    fmt::print(out_, "waiting ({}): {}\n", request.id, request.text);
    std::fflush(out_);
  }
}

Progress ScriptedOperator::poll(const Request& request) {
  if (auto it = answers_.find(request.id); it != answers_.end()) {
    return it->second == "abort" ? Progress::kAbort : Progress::kDone;
  }
  return Progress::kWaiting;
}

std::optional<std::string> ScriptedOperator::ask(const Request& request) {
  if (auto it = answers_.find(request.id); it != answers_.end()) return it->second;
  return std::nullopt;
}

}  // namespace toonforce::bringup
