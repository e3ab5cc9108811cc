// Config: JSON components chosen by "type" (alias "otype", as tiny-cuda-nn), read by a Reader that checks
// every key and records what it read, so that
//   - unknown keys, wrong types and out-of-range values are ConfigErrors naming the JSON pointer and the
//     valid choices;
//   - every component can return its fully resolved hyperparameters (Reader::resolved());
//   - docs/config.md is generated from the very code that parses configs (Registry::describe()).
//
//   Reader r(json, "/network", "FullyFusedMLP");
//   uint32_t width = r.choice<uint32_t>("n_neurons", 64, {16, 32, 64, 128, 256}, "hidden layer width");
//   float lr = r.number("learning_rate", 1e-2f, 0.0f, 1.0f, "step size");
//   r.finish();                       // throws for keys nobody read
#pragma once

#include <relit/error.hpp>

#include <nlohmann/json.hpp>

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace relit {

using Json = nlohmann::json;

/// Parses JSON `text` read from `source` (a file name, or a description such as "the --config argument").
/// Stricter than the JSON library: an object with the same key twice is refused, since which of the two is
/// meant cannot be known. Throws ConfigError naming `source`, the position and the cause for invalid JSON, a
/// number outside the double range (1e999) and duplicate keys.
Json parse_json(const std::string& text, const std::string& source);

namespace config {

/// One parameter as a component reads it: the source of the generated config reference.
struct ParamDoc {
  std::string key;
  std::string type;    ///< "uint", "float", "bool", "string", "array", "object", "component"
  Json default_value;  ///< null when required
  std::string valid;   ///< "16, 32, 64", "[0, 1]", ... ("" when anything of the type goes)
  std::string description;
};

/// The keys of a structured config, object by object: (JSON pointer of the object, its keys).
using Docs = std::vector<std::pair<std::string, std::vector<ParamDoc>>>;

class Reader {
 public:
  /// `pointer` is where `json` sits in the whole document ("" for the root); `component` names the thing
  /// being configured in messages ("HashGrid").
  Reader(const Json& json, std::string pointer, std::string component);

  /// An unsigned integer in [lo, hi].
  std::uint32_t uint(const std::string& key, std::uint32_t def, std::uint32_t lo, std::uint32_t hi,
                     const std::string& description);
  /// A finite number in [lo, hi].
  float number(const std::string& key, float def, float lo, float hi, const std::string& description);
  bool boolean(const std::string& key, bool def, const std::string& description);
  /// A string from `choices` (compared case-insensitively; the canonical spelling is returned).
  std::string choice(const std::string& key, const std::string& def, const std::vector<std::string>& choices,
                     const std::string& description);
  /// A number from `choices` (e.g. widths 16, 32, 64, 128, 256).
  std::uint32_t uint_choice(const std::string& key, std::uint32_t def, const std::vector<std::uint32_t>& choices,
                            const std::string& description);
  /// A list of unsigned integers, each in [lo, hi].
  std::vector<std::uint32_t> uint_list(const std::string& key, const std::vector<std::uint32_t>& def, std::uint32_t lo,
                                       std::uint32_t hi, const std::string& description);
  /// A free string.
  std::string string(const std::string& key, const std::string& def, const std::string& description);
  /// A nested JSON value for a sub-component ({} when absent); the caller reads it with its own Reader and
  /// stores the resolved result with set_resolved().
  Json sub(const std::string& key, const Json& def, const std::string& type, const std::string& description);
  void set_resolved(const std::string& key, Json value);

  bool has(const std::string& key) const;
  /// The JSON pointer of `key` inside this reader ("/network/n_neurons").
  std::string pointer(const std::string& key = "") const;
  [[noreturn]] void fail(const std::string& key, const std::string& message) const;

  /// Throws ConfigError for every key that was present but never read, listing the valid keys.
  void finish() const;
  /// Every key with the value in force (given or default): the component's resolved hyperparameters.
  const Json& resolved() const { return m_resolved; }
  const std::vector<ParamDoc>& docs() const { return m_docs; }
  const std::string& component() const { return m_component; }

 private:
  const Json* find(const std::string& key);
  void record(const std::string& key, const std::string& type, const Json& def, const std::string& valid,
              const std::string& description, const Json& value);

  Json m_json;
  std::string m_pointer, m_component;
  std::vector<std::string> m_read;
  Json m_resolved = Json::object();
  std::vector<ParamDoc> m_docs;
};

/// The "type" of a component object (or its alias "otype"); `def` when absent. ConfigError if not a string.
std::string component_type(const Json& json, const std::string& pointer, const std::string& def);

/// A family of components (encodings, networks, losses, optimisers, ...) built from JSON by "type".
template <class Base, class... Args>
class Registry {
 public:
  using Factory = std::function<std::unique_ptr<Base>(Reader&, Args...)>;
  struct Entry {
    std::string type, description;
    Factory factory;
  };

  explicit Registry(std::string family, std::string default_type = "")
      : m_family(std::move(family)), m_default(std::move(default_type)) {}

  void add(const std::string& type, const std::string& description, Factory factory) {
    m_entries.push_back({type, description, std::move(factory)});
  }

  /// Builds the component described by `json` (found at `pointer`); "type" selects the factory. The
  /// resolved hyperparameters (with "type") are returned through `resolved` when it is non-null.
  std::unique_ptr<Base> create(const Json& json, const std::string& pointer, Args... args,
                               Json* resolved = nullptr) const {
    if (!json.is_object()) throw ConfigError(pointer, m_family + " config must be a JSON object, got " + json.dump());
    const std::string type = component_type(json, pointer, m_default);
    const Entry& e = entry(type, pointer);
    Json body = json;
    body.erase("type");
    body.erase("otype");
    Reader reader(body, pointer, e.type);
    auto object = e.factory(reader, args...);
    reader.finish();
    if (resolved) {
      *resolved = Json{{"type", e.type}};
      resolved->update(reader.resolved());
    }
    return object;
  }

  const Entry& entry(const std::string& type, const std::string& pointer = "") const {
    for (const auto& e : m_entries)
      if (lower(e.type) == lower(type)) return e;
    std::string valid;
    for (const auto& e : m_entries) valid += (valid.empty() ? "" : ", ") + e.type;
    throw ConfigError(pointer.empty() ? "/type" : pointer + "/type",
                      "unknown " + m_family + " type '" + type + "'; valid types: " + valid);
  }
  const std::vector<Entry>& entries() const { return m_entries; }
  const std::string& family() const { return m_family; }
  const std::string& default_type() const { return m_default; }

 private:
  static std::string lower(std::string s) {
    for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return s;
  }
  std::string m_family, m_default;
  std::vector<Entry> m_entries;
};

}  // namespace config
}  // namespace relit
