// The control protocol's messages (control_protocol.hpp; docs/spec/control-protocol.md).
// Parsing with nlohmann's JSON (Debian's nlohmann-json3-dev); a change's keys are written as
// TOML so that the scene files' reader checks them with its own rules and messages.

#include "toonforce/viewer/control_protocol.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <random>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "toonforce/viewer/scene_json.hpp"

namespace toonforce::viewer {

namespace {

using nlohmann::json;

std::string dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

/// A TOML basic string.
std::string toml_string(std::string_view s) {
  std::string out = "\"";
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (u < 0x20 || u == 0x7f) {
      out += fmt::format("\\u{:04X}", static_cast<unsigned>(u));
    } else {
      out += c;
    }
  }
  return out + "\"";
}

/// A JSON value as a TOML value (numbers, booleans, strings, arrays, objects as inline tables).
Result<std::string> toml_value(const json& v, const std::string& path) {
  switch (v.type()) {
    case json::value_t::number_integer: return fmt::format("{}", v.get<std::int64_t>());
    case json::value_t::number_unsigned: return fmt::format("{}", v.get<std::uint64_t>());
    case json::value_t::number_float: {
      const double d = v.get<double>();
      // The shortest text that reads back as the same double; TOML wants a digit before an exponent.
      std::string text = fmt::format("{}", d);
      if (text.find_first_of(".eEn") == std::string::npos) text += ".0";
      return text;
    }
    case json::value_t::boolean: return std::string(v.get<bool>() ? "true" : "false");
    case json::value_t::string: return toml_string(v.get<std::string>());
    case json::value_t::array: {
      std::string out = "[";
      for (std::size_t i = 0; i < v.size(); ++i) {
        auto item = toml_value(v[i], fmt::format("{}[{}]", path, i));
        if (!item) return item;
        out += (i == 0 ? "" : ", ") + item.value();
      }
      return out + "]";
    }
    case json::value_t::object: {
      std::string out = "{";
      bool first = true;
      for (const auto& [key, item] : v.items()) {
        auto value = toml_value(item, path + "." + key);
        if (!value) return value;
        out += fmt::format("{}{} = {}", first ? "" : ", ", toml_string(key), value.value());
        first = false;
      }
      return out + "}";
    }
    default: return Error{fmt::format("{}: null is not a value of a scene", path)};
  }
}

/// An effect's keys, one per line (a message's "keys" object).
Result<std::string> toml_keys(const json& keys) {
  std::string out;
  for (const auto& [key, value] : keys.items()) {
    auto text = toml_value(value, key);
    if (!text) return text;
    out += fmt::format("{} = {}\n", toml_string(key), text.value());
  }
  return out;
}

/// Constant time in the length of `given`: a wrong token takes as long whatever its prefix.
bool same_token(std::string_view given, std::string_view token) {
  unsigned diff = given.size() == token.size() ? 0U : 1U;
  for (std::size_t i = 0; i < given.size(); ++i) {
    diff |= static_cast<unsigned>(static_cast<unsigned char>(given[i]) ^
                                  static_cast<unsigned char>(token.empty() ? 0 : token[i % token.size()]));
  }
  return diff == 0 && !token.empty();
}

struct Message {
  std::string_view type;
  std::vector<std::string_view> required;
  std::vector<std::string_view> optional;
};
const std::array<Message, 8> kMessages{{
    {"hello", {"version", "token"}, {}},
    {"set", {"effect", "keys"}, {}},
    {"add", {"kind", "keys"}, {}},
    {"remove", {"effect"}, {}},
    {"load", {"toml"}, {"name"}},
    {"fire", {"effect", "event"}, {"value"}},
    {"status", {}, {}},
    {"scene", {}, {}},
}};

std::string type_list() {
  std::string out;
  for (const Message& m : kMessages) out += fmt::format("{}{}", out.empty() ? "" : ", ", m.type);
  return out;
}

/// Every field of `m` known and of the right kind; the message's problem otherwise.
std::string check_fields(const json& m, const Message& spec) {
  for (const auto& [key, value] : m.items()) {
    if (key == "type" || key == "id") continue;
    const bool known = std::find(spec.required.begin(), spec.required.end(), key) != spec.required.end() ||
                       std::find(spec.optional.begin(), spec.optional.end(), key) != spec.optional.end();
    if (!known) return fmt::format("'{}' has no field '{}'", spec.type, key);
  }
  for (const std::string_view key : spec.required) {
    if (!m.contains(key)) return fmt::format("'{}' needs the field '{}'", spec.type, key);
  }
  for (const auto& [key, value] : m.items()) {
    const bool text = key == "token" || key == "effect" || key == "kind" || key == "toml" || key == "name" ||
                      key == "event";
    if (text && !value.is_string()) return fmt::format("'{}': '{}' must be a string", spec.type, key);
    if ((key == "value" || key == "version") && !value.is_number()) {
      return fmt::format("'{}': '{}' must be a number", spec.type, key);
    }
    if (key == "keys" && !value.is_object()) {
      return fmt::format("'{}': 'keys' must be an object of the effect's keys, as in a scene file", spec.type);
    }
  }
  return {};
}

}  // namespace

template <Scalar S>
std::string EditorControl<S>::scene_json() const {
  return viewer::scene_json(editor_.scene());
}
template class EditorControl<double>;
template class EditorControl<float>;
template class EditorControl<Q16_16>;

std::string random_token() {
  std::random_device source;  // the system's (getrandom, /dev/urandom)
  std::string out;
  for (int i = 0; i < 4; ++i) out += fmt::format("{:08x}", static_cast<std::uint32_t>(source()));
  return out;
}

ControlSession::Reply ControlSession::on_message(std::string_view text, double now_s) {
  json id;  // echoed in the reply when the message has one
  const auto error = [&](std::string message, bool close = false) {
    ++refused_;
    while (!message.empty() && message.back() == '\n') message.pop_back();
    json reply{{"type", "error"}, {"message", message}};
    if (!id.is_null()) reply["id"] = id;
    return Reply{dump(reply), close};
  };
  try {
    // The rate limit first: a flood costs no parsing.
    if (tokens_ < 0.0) {
      tokens_ = options_.burst_messages;
      last_s_ = now_s;
    }
    tokens_ = std::min(options_.burst_messages, tokens_ + std::max(0.0, now_s - last_s_) * options_.max_messages_per_s);
    last_s_ = now_s;
    if (tokens_ < 1.0) {
      return error(fmt::format("rate limit: at most {} messages a second (bursts of {}); this one changed nothing",
                               options_.max_messages_per_s, options_.burst_messages));
    }
    tokens_ -= 1.0;
    if (text.size() > options_.max_message_bytes) {
      return error(fmt::format("a message of {} bytes; at most {}", text.size(), options_.max_message_bytes));
    }
    const json m = json::parse(text, nullptr, false);
    if (m.is_discarded()) return error("not JSON");
    if (!m.is_object()) return error("a message is a JSON object with a \"type\"");
    if (m.contains("id")) id = m["id"];
    if (!m.contains("type") || !m["type"].is_string()) return error("a message needs a \"type\": " + type_list());
    const std::string type = m["type"].get<std::string>();
    const auto spec = std::find_if(kMessages.begin(), kMessages.end(), [&](const Message& s) { return s.type == type; });
    if (spec == kMessages.end()) return error(fmt::format("unknown type '{}'; the types are {}", type, type_list()));
    if (const std::string problem = check_fields(m, *spec); !problem.empty()) return error(problem, !authenticated_);

    if (!authenticated_) {
      if (type != "hello") return error("the first message must be a hello with the token", true);
      if (m["version"] != kControlProtocolVersion) {
        return error(fmt::format("protocol version {} is not spoken here; this server speaks {}", dump(m["version"]),
                                 kControlProtocolVersion),
                     true);
      }
      if (!same_token(m["token"].get<std::string>(), options_.token)) return error("wrong token", true);
      authenticated_ = true;
      json reply{{"type", "welcome"},
                 {"version", kControlProtocolVersion},
                 {"applied", control_.applied()},
                 {"scene", json::parse(control_.scene_json(), nullptr, false)}};
      if (!id.is_null()) reply["id"] = id;
      return {dump(reply), false};
    }
    if (type == "hello") return error("already said hello");
    if (type == "status" || type == "scene") {
      json reply{{"type", type}, {"applied", control_.applied()}};
      if (type == "scene") reply["scene"] = json::parse(control_.scene_json(), nullptr, false);
      if (!id.is_null()) reply["id"] = id;
      return {dump(reply), false};
    }

    Result<std::uint64_t> sent = Error{""};
    if (type == "set" || type == "add") {
      auto keys = toml_keys(m["keys"]);
      if (!keys) return error(keys.error());
      sent = type == "set" ? control_.set(m["effect"].get<std::string>(), keys.value())
                           : control_.add(m["kind"].get<std::string>(), keys.value());
    } else if (type == "remove") {
      sent = control_.remove(m["effect"].get<std::string>());
    } else if (type == "load") {
      sent = control_.load(m["toml"].get<std::string>(), m.contains("name") ? m["name"].get<std::string>() : "load");
    } else if (type == "fire") {
      const double value = m.contains("value") ? m["value"].get<double>() : 0.0;
      sent = control_.fire(m["effect"].get<std::string>(), m["event"].get<std::string>(), value);
    }
    if (!sent) return error(sent.error());
    json reply{{"type", "ok"}, {"sequence", sent.value()}};
    if (!id.is_null()) reply["id"] = id;
    return {dump(reply), false};
  } catch (const std::exception& e) {  // the server's thread: a message never ends it
    return error(fmt::format("refused: {}", e.what()));
  }
}

}  // namespace toonforce::viewer
