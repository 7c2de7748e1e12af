// SPDX-License-Identifier: Apache-2.0
#pragma once
/// The person at the device during a bring-up. The bring-up says what to do and asks what it
/// cannot measure; the Operator is how that reaches a person (ConsoleOperator: interactive, on
/// a terminal), a script (ScriptedOperator: answers given on the command line, nothing else)
/// or a test (an emulated person acting on an emulated device). Every request has a stable id
/// ("falcon.homing", "falcon.led.red") that scripts answer and tests act on.

#include <cstdio>
#include <map>
#include <optional>
#include <string>
#include <string_view>

namespace toonforce::bringup {

struct Request {
  std::string id;    ///< stable: what --answer ID=VALUE and tests name
  std::string text;  ///< for the person
};

enum class Progress : std::uint8_t {
  kWaiting,  ///< nothing from the person yet
  kDone,     ///< the person says it is done (Enter)
  kAbort,    ///< the person wants to stop (q): forces off, the report says so
};

class Operator {
 public:
  virtual ~Operator() = default;
  /// Progress and results, one line each.
  virtual void say(std::string_view line) = 0;
  /// A wait begins: the person is told what to do (request.text).
  virtual void begin(const Request& request) = 0;
  /// Called again and again during that wait (while the device keeps running): must return at
  /// once. The bring-up also ends a wait by itself when it sees what it waits for.
  virtual Progress poll(const Request& request) = 0;
  /// A question the device cannot answer ("is the LED red?", "the mass of the weight"): the
  /// answer, or nullopt when none can be given (a script without it).
  virtual std::optional<std::string> ask(const Request& request) = 0;
  /// True when a person is there to act (not a script): steps that need one are skipped
  /// otherwise, unless the script answers for them.
  virtual bool interactive() const = 0;
};

/// A person at a terminal: instructions and results on `out`, Enter on `in` ends a wait ("q"
/// aborts), questions read a line. `answers` pre-answer requests by id (--answer).
class ConsoleOperator final : public Operator {
 public:
  ConsoleOperator(std::FILE* in, std::FILE* out, std::map<std::string, std::string> answers = {});
  void say(std::string_view line) override;
  void begin(const Request& request) override;
  Progress poll(const Request& request) override;
  std::optional<std::string> ask(const Request& request) override;
  bool interactive() const override { return true; }

 private:
  std::FILE* in_;
  std::FILE* out_;
  std::map<std::string, std::string> answers_;
  std::string pending_;  // a partial line typed so far
};

/// No person: answers only what `answers` holds (by request id); a wait whose id is answered
/// ("done") ends at once, any other ends only when the device shows what it waits for.
class ScriptedOperator final : public Operator {
 public:
  explicit ScriptedOperator(std::map<std::string, std::string> answers = {}, std::FILE* out = nullptr);
  void say(std::string_view line) override;
  void begin(const Request& request) override;
  Progress poll(const Request& request) override;
  std::optional<std::string> ask(const Request& request) override;
  bool interactive() const override { return false; }

 private:
  std::map<std::string, std::string> answers_;
  std::FILE* out_;
};

/// "yes", "y", "true", "1" (any case) -> true; "no", "n", "false", "0" -> false; else nullopt.
std::optional<bool> parse_yes_no(std::string_view text);

}  // namespace toonforce::bringup
