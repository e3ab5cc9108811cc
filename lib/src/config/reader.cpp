// The config Reader: typed, range-checked access to JSON that records what it read.
#include <relit/config.hpp>

#include "shared.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

namespace relit {

Json parse_json(const std::string& text, const std::string& source) {
  // The parser's callback sees every key with its depth: one key set per open object finds duplicates, and
  // the last key at each depth gives the object's place for the message.
  std::vector<std::set<std::string>> keys;
  std::vector<std::string> path;
  std::string duplicate;
  auto check = [&](int depth, Json::parse_event_t event, Json& value) {
    const auto d = static_cast<std::size_t>(depth);
    if (event == Json::parse_event_t::object_start) {
      if (keys.size() < d + 2) keys.resize(d + 2), path.resize(d + 2);
      keys[d + 1].clear();
    } else if (event == Json::parse_event_t::key && duplicate.empty() && d < keys.size()) {
      const std::string key = value.get<std::string>();
      path[d] = key;
      if (!keys[d].insert(key).second) {
        std::string where;
        for (std::size_t i = 1; i < d; ++i) where += "/" + path[i];
        duplicate = "key \"" + key + "\" appears twice in the object at '" + (where.empty() ? "/" : where) + "'";
      }
    }
    return true;
  };
  Json j;
  try {
    j = Json::parse(text, check);
  } catch (const Json::parse_error& e) {
    throw ConfigError("", source + " is not valid JSON: " + e.what());
  } catch (const Json::out_of_range& e) {
    throw ConfigError("", source + " holds a number outside the range of a double: " + e.what());
  } catch (const Json::exception& e) {
    throw ConfigError("", source + " cannot be read as JSON: " + e.what());
  }
  if (!duplicate.empty()) throw ConfigError("", source + ": " + duplicate + "; keep one");
  return j;
}

}  // namespace relit

namespace relit::config {

namespace {

using ::relit::detail::lower;

std::string type_name(const Json& j) {
  if (j.is_boolean()) return "a boolean";
  if (j.is_number_unsigned() || j.is_number_integer()) return "an integer";
  if (j.is_number()) return "a number";
  if (j.is_string()) return "a string";
  if (j.is_array()) return "an array";
  if (j.is_object()) return "an object";
  return "null";
}

template <class T>
std::string join(const std::vector<T>& items) {
  std::ostringstream s;
  for (std::size_t i = 0; i < items.size(); ++i) s << (i ? ", " : "") << items[i];
  return s.str();
}

std::string escape_pointer_token(const std::string& key) {
  std::string out;
  for (char c : key) {
    if (c == '~')
      out += "~0";
    else if (c == '/')
      out += "~1";
    else
      out += c;
  }
  return out;
}

}  // namespace

Reader::Reader(const Json& json, std::string pointer, std::string component)
    : m_json(json), m_pointer(std::move(pointer)), m_component(std::move(component)) {
  if (!m_json.is_object() && !m_json.is_null())
    throw ConfigError(m_pointer, m_component + " config must be a JSON object, got " + type_name(m_json));
  if (m_json.is_null()) m_json = Json::object();
}

std::string Reader::pointer(const std::string& key) const {
  return key.empty() ? m_pointer : m_pointer + "/" + escape_pointer_token(key);
}

void Reader::fail(const std::string& key, const std::string& message) const {
  throw ConfigError(pointer(key), message);
}

bool Reader::has(const std::string& key) const { return m_json.contains(key); }

const Json* Reader::find(const std::string& key) {
  m_read.push_back(key);
  auto it = m_json.find(key);
  return it == m_json.end() ? nullptr : &*it;
}

void Reader::record(const std::string& key, const std::string& type, const Json& def, const std::string& valid,
                    const std::string& description, const Json& value) {
  m_docs.push_back({key, type, def, valid, description});
  m_resolved[key] = value;
}

std::uint32_t Reader::uint(const std::string& key, std::uint32_t def, std::uint32_t lo, std::uint32_t hi,
                           const std::string& description) {
  std::uint32_t value = def;
  if (const Json* j = find(key)) {
    const bool integral = j->is_number_integer() || j->is_number_unsigned() ||
                          (j->is_number_float() && std::floor(j->get<double>()) == j->get<double>());
    if (!integral)
      fail(key, "must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + j->dump());
    const double v = j->get<double>();
    if (v < lo || v > hi)
      fail(key, "must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + j->dump());
    value = static_cast<std::uint32_t>(v);
  }
  record(key, "uint", def, "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]", description, value);
  return value;
}

float Reader::number(const std::string& key, float def, float lo, float hi, const std::string& description) {
  float value = def;
  std::ostringstream range;
  range << "[" << lo << ", " << hi << "]";
  if (const Json* j = find(key)) {
    if (!j->is_number()) fail(key, "must be a number in " + range.str() + ", got " + type_name(*j) + " " + j->dump());
    const double v = j->get<double>();
    if (!std::isfinite(v) || v < lo || v > hi) fail(key, "must be in " + range.str() + ", got " + j->dump());
    value = static_cast<float>(v);
  }
  record(key, "float", def, range.str(), description, value);
  return value;
}

bool Reader::boolean(const std::string& key, bool def, const std::string& description) {
  bool value = def;
  if (const Json* j = find(key)) {
    if (!j->is_boolean()) fail(key, "must be true or false, got " + j->dump());
    value = j->get<bool>();
  }
  record(key, "bool", def, "true, false", description, value);
  return value;
}

std::string Reader::choice(const std::string& key, const std::string& def, const std::vector<std::string>& choices,
                           const std::string& description) {
  std::string value = def;
  if (const Json* j = find(key)) {
    if (!j->is_string()) fail(key, "must be one of " + join(choices) + "; got " + j->dump());
    const std::string given = j->get<std::string>();
    const auto it =
        std::find_if(choices.begin(), choices.end(), [&](const std::string& c) { return lower(c) == lower(given); });
    if (it == choices.end()) fail(key, "must be one of " + join(choices) + "; got \"" + given + "\"");
    value = *it;
  }
  record(key, "string", def, join(choices), description, value);
  return value;
}

std::uint32_t Reader::uint_choice(const std::string& key, std::uint32_t def, const std::vector<std::uint32_t>& choices,
                                  const std::string& description) {
  std::uint32_t value = def;
  if (const Json* j = find(key)) {
    const bool integral = j->is_number_integer() || j->is_number_unsigned();
    if (!integral || std::find(choices.begin(), choices.end(), j->get<double>()) == choices.end())
      fail(key, "must be one of " + join(choices) + "; got " + j->dump());
    value = j->get<std::uint32_t>();
  }
  record(key, "uint", def, join(choices), description, value);
  return value;
}

std::vector<std::uint32_t> Reader::uint_list(const std::string& key, const std::vector<std::uint32_t>& def,
                                             std::uint32_t lo, std::uint32_t hi, const std::string& description) {
  std::vector<std::uint32_t> value = def;
  const std::string range = "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
  if (const Json* j = find(key)) {
    if (!j->is_array()) fail(key, "must be a list of integers in " + range + ", got " + j->dump());
    value.clear();
    for (std::size_t i = 0; i < j->size(); ++i) {
      const Json& e = (*j)[i];
      if (!(e.is_number_integer() || e.is_number_unsigned()) || e.get<double>() < lo || e.get<double>() > hi)
        throw ConfigError(pointer(key) + "/" + std::to_string(i),
                          "must be an integer in " + range + ", got " + e.dump());
      value.push_back(e.get<std::uint32_t>());
    }
  }
  record(key, "array", def, "integers in " + range, description, value);
  return value;
}

std::string Reader::string(const std::string& key, const std::string& def, const std::string& description) {
  std::string value = def;
  if (const Json* j = find(key)) {
    if (!j->is_string()) fail(key, "must be a string, got " + j->dump());
    value = j->get<std::string>();
  }
  record(key, "string", def, "", description, value);
  return value;
}

Json Reader::sub(const std::string& key, const Json& def, const std::string& type, const std::string& description) {
  const Json* j = find(key);
  // An object section or component given as something else ("model": [], "training": null) is refused here,
  // where its pointer is known; null stands for "none" only where that is the default.
  if (j && (type == "object" || type == "component") && !j->is_object() && !(j->is_null() && def.is_null()))
    fail(key, "must be a JSON object (" + description + "), got " +
                  (j->is_null() ? std::string("null") : type_name(*j) + " " + j->dump().substr(0, 80)));
  const Json value = j ? *j : def;
  m_docs.push_back({key, type, def, "", description});
  m_resolved[key] = value;
  return value;
}

void Reader::set_resolved(const std::string& key, Json value) { m_resolved[key] = std::move(value); }

void Reader::finish() const {
  for (auto it = m_json.begin(); it != m_json.end(); ++it) {
    if (std::find(m_read.begin(), m_read.end(), it.key()) != m_read.end()) continue;
    std::vector<std::string> valid;
    for (const auto& d : m_docs) valid.push_back(d.key);
    throw ConfigError(pointer(it.key()),
                      "unknown key '" + it.key() + "' for " + m_component +
                          (valid.empty() ? " (it takes no parameters)" : "; valid keys: " + join(valid)));
  }
}

std::string component_type(const Json& json, const std::string& pointer, const std::string& def) {
  const auto type = json.find("type"), otype = json.find("otype");
  if (type != json.end() && otype != json.end() && *type != *otype)
    throw ConfigError(pointer, "\"type\" (" + type->dump() + ") and its alias \"otype\" (" + otype->dump() +
                                   ") disagree; give one of them");
  for (const char* key : {"type", "otype"}) {
    auto it = json.find(key);
    if (it == json.end()) continue;
    if (!it->is_string()) throw ConfigError(pointer + "/" + key, "must be a string naming the component type");
    return it->get<std::string>();
  }
  if (def.empty()) throw ConfigError(pointer, "missing \"type\"");
  return def;
}

}  // namespace relit::config
