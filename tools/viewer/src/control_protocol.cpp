// SPDX-License-Identifier: Apache-2.0
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

/// A name quoted from a message in a reply: at most kControlMaxEchoBytes of it.
std::string shown(std::string_view name) {
  if (name.size() <= kControlMaxEchoBytes) return std::string(name);
  return fmt::format("{}... ({} bytes)", name.substr(0, kControlMaxEchoBytes), name.size());
}

/// Where a value is in a message's keys, for messages only: one step per level, made into text
/// only when a value is refused (copying the path at every level cost a copy of it per level).
struct PathStep {
  std::string_view key;  ///< an object's key, or empty for an array's item
  std::size_t index = 0;
};
std::string path_text(const std::vector<PathStep>& path) {
  std::string out;
  for (std::size_t i = 0; i < path.size(); ++i) {
    if (path[i].key.data() == nullptr) {
      out += fmt::format("[{}]", path[i].index);
    } else {
      if (i != 0) out += '.';
      out += shown(path[i].key);
    }
  }
  return out;
}

/// A JSON value as a TOML value (numbers, booleans, strings, arrays, objects as inline tables).
/// Recursive, to the depth of the message: kControlMaxDepth, checked before it was parsed.
Result<std::string> toml_value(const json& v, std::vector<PathStep>& path) {
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
    case json::value_t::string: return toml_string(v.get_ref<const std::string&>());
    case json::value_t::array: {
      std::string out = "[";
      for (std::size_t i = 0; i < v.size(); ++i) {
        path.push_back(PathStep{{}, i});
        auto item = toml_value(v[i], path);
        path.pop_back();
        if (!item) return item;
        if (i != 0) out += ", ";
        out += item.value();
      }
      return out + "]";
    }
    case json::value_t::object: {
      std::string out = "{";
      bool first = true;
      for (const auto& [key, item] : v.items()) {
        path.push_back(PathStep{key, 0});
        auto value = toml_value(item, path);
        path.pop_back();
        if (!value) return value;
        out += fmt::format("{}{} = {}", first ? "" : ", ", toml_string(key), value.value());
        first = false;
      }
      return out + "}";
    }
    default: return Error{fmt::format("{}: null is not a value of a scene", path_text(path))};
  }
}

/// An effect's keys, one per line (a message's "keys" object).
Result<std::string> toml_keys(const json& keys) {
  std::string out;
  std::vector<PathStep> path;
  path.reserve(kControlMaxDepth);
  for (const auto& [key, value] : keys.items()) {
    path.assign(1, PathStep{key, 0});
    auto text = toml_value(value, path);
    if (!text) return text;
    out += fmt::format("{} = {}\n", toml_string(key), text.value());
  }
  return out;
}

/// What makes a message's text unfit to parse, found in one pass over it: a NUL byte, or arrays
/// and objects nested deeper than kControlMaxDepth (counted outside strings). Empty: none.
std::string scan_problem(std::string_view text) {
  std::size_t depth = 0;
  bool in_string = false;
  bool escaped = false;
  for (const char c : text) {
    if (c == '\0') return "a message may not contain a NUL byte";
    if (in_string) {
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kControlMaxDepth) {
        return fmt::format("arrays and objects nest at most {} levels deep (the message is level 1)", kControlMaxDepth);
      }
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return {};
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
    if (!known) return fmt::format("'{}' has no field '{}'", spec.type, shown(key));
  }
  for (const std::string_view key : spec.required) {
    if (!m.contains(key)) return fmt::format("'{}' needs the field '{}'", spec.type, key);
  }
  for (const auto& [key, value] : m.items()) {
    const bool text =
        key == "token" || key == "effect" || key == "kind" || key == "toml" || key == "name" || key == "event";
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

namespace {

/// The message parsed, or why not: a key given twice in an object (at any level) is refused,
/// never resolved by taking one of them (a wrong "token" then the right one passed that way).
/// Called only on text scan_problem() passed: depth bounded, no NUL.
std::string parse_message(std::string_view text, json& out) {
  std::vector<std::vector<std::string>> open_objects;  // the keys seen in each object being read
  std::string duplicate;
  bool found = false;
  const json::parser_callback_t keys = [&](int, json::parse_event_t event, json& parsed) {
    if (event == json::parse_event_t::object_start) {
      open_objects.emplace_back();
    } else if (event == json::parse_event_t::object_end) {
      if (!open_objects.empty()) open_objects.pop_back();
    } else if (event == json::parse_event_t::key && !open_objects.empty() && parsed.is_string()) {
      auto& seen = open_objects.back();
      const std::string& key = parsed.get_ref<const std::string&>();
      if (std::find(seen.begin(), seen.end(), key) != seen.end()) {
        if (!found) duplicate = key;
        found = true;
      } else {
        seen.push_back(key);
      }
    }
    return true;
  };
  out = json::parse(text, keys, false);
  if (out.is_discarded()) return "not JSON";
  if (found) return fmt::format("the key '{}' is given twice in an object; each key once", shown(duplicate));
  return {};
}

}  // namespace

ControlSession::Reply ControlSession::on_message(std::string_view text, double now_s) {
  json id;  // echoed in the reply when the message has one (null too)
  bool has_id = false;
  const auto error = [&](std::string message, bool close = false) {
    ++refused_;
    while (!message.empty() && message.back() == '\n') message.pop_back();
    if (message.size() > kControlMaxErrorBytes) {
      message.resize(kControlMaxErrorBytes);
      message += "...";
    }
    json reply{{"type", "error"}, {"message", message}};
    if (has_id) reply["id"] = id;
    // Before the hello every refusal ends the connection (1008): a first message that is not
    // a good hello, whatever is wrong with it.
    return Reply{dump(reply), close || !authenticated_};
  };
  const auto answer = [&](json reply) {
    if (has_id) reply["id"] = id;
    return Reply{dump(reply), false};
  };
  try {
    // Bounded before anything is parsed: the size, then one pass for NUL bytes and depth.
    if (text.size() > options_.max_message_bytes) {
      return error(fmt::format("a message of {} bytes; at most {}", text.size(), options_.max_message_bytes));
    }
    if (const std::string problem = scan_problem(text); !problem.empty()) return error(problem);
    json m;
    if (const std::string problem = parse_message(text, m); !problem.empty()) return error(problem);
    if (!m.is_object()) return error("a message is a JSON object with a \"type\"");
    if (const auto it = m.find("id"); it != m.end()) {
      const bool short_string = it->is_string() && it->get_ref<const std::string&>().size() <= kControlMaxIdBytes;
      if (!(it->is_number() || it->is_boolean() || it->is_null() || short_string)) {
        return error(fmt::format("an \"id\" is a number, a string of at most {} bytes, true, false or null",
                                 kControlMaxIdBytes));
      }
      id = *it;
      has_id = true;
    }
    // The rate limit, with the id known: a refused message's reply carries it too.
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
    if (!m.contains("type") || !m["type"].is_string()) return error("a message needs a \"type\": " + type_list());
    const std::string type = m["type"].get<std::string>();
    const auto spec =
        std::find_if(kMessages.begin(), kMessages.end(), [&](const Message& s) { return s.type == type; });
    if (spec == kMessages.end()) {
      return error(fmt::format("unknown type '{}'; the types are {}", shown(type), type_list()));
    }
    if (const std::string problem = check_fields(m, *spec); !problem.empty()) return error(problem);

    if (!authenticated_) {
      if (type != "hello") return error("the first message must be a hello with the token", true);
      if (m["version"] != kControlProtocolVersion) {
        return error(fmt::format("protocol version {} is not spoken here; this server speaks {}",
                                 shown(dump(m["version"])), kControlProtocolVersion),
                     true);
      }
      if (!same_token(m["token"].get<std::string>(), options_.token)) return error("wrong token", true);
      authenticated_ = true;
      return answer(json{{"type", "welcome"},
                         {"version", kControlProtocolVersion},
                         {"applied", control_.applied()},
                         {"scene", json::parse(control_.scene_json(), nullptr, false)}});
    }
    if (type == "hello") return error("already said hello");
    if (type == "status" || type == "scene") {
      json reply{{"type", type}, {"applied", control_.applied()}};
      if (type == "scene") reply["scene"] = json::parse(control_.scene_json(), nullptr, false);
      return answer(std::move(reply));
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
    if (type != "fire") ++changes_;
    return answer(json{{"type", "ok"}, {"sequence", sent.value()}});
  } catch (const std::exception& e) {  // the server's thread: a message never ends it
    return error(fmt::format("refused: {}", e.what()));
  }
}

}  // namespace toonforce::viewer
