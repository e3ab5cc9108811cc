// The preset run configs (configs/*.json, embedded in the library) and loading a run config by name or file.
#include <relit/io/file.hpp>
#include <relit/method/model.hpp>
#include <relit/method/presets.hpp>

#include "embedded_files.hpp"

#include <algorithm>
#include <filesystem>

namespace fs = std::filesystem;

namespace relit::method {

std::vector<std::string> preset_names() {
  std::vector<std::string> names;
  for (const auto& f : ::relit::detail::embedded_presets()) {
    std::string n = f.name;
    names.push_back(n.substr(0, n.size() - 5));  // drop ".json"
  }
  return names;
}

namespace {
std::string join(const std::vector<std::string>& v) {
  std::string out;
  for (const auto& s : v) out += (out.empty() ? "" : ", ") + s;
  return out;
}
}  // namespace

Json preset(const std::string& name) {
  for (const auto& f : ::relit::detail::embedded_presets())
    if (name + ".json" == f.name) return parse_json(f.text, "preset '" + name + "'");
  throw InvalidArgument("unknown preset '" + name + "'; presets: " + join(preset_names()) + " (or give a .json file)");
}

Json load_run_config(const std::string& spec) {
  const auto names = preset_names();
  if (std::find(names.begin(), names.end(), spec) != names.end()) return preset(spec);
  if (!fs::exists(spec))
    throw IOError("config '" + spec + "' is neither a preset (" + join(names) + ") nor an existing file");
  return parse_json(io::read_file(spec), spec);
}

std::string config_for_method(const std::string& spec, const std::string& method) {
  if (method.empty()) return spec;
  const auto methods = method_names();
  if (std::find(methods.begin(), methods.end(), method) == methods.end())
    throw InvalidArgument("unknown method '" + method + "'; methods: " + join(methods));
  if (method == "ours" || (spec != "fast" && spec != "paper")) return spec;
  return method + "-" + spec;
}

void set_method(Json& config, const std::string& method, const std::string& source) {
  if (method.empty()) return;
  config_for_method("fast", method);  // an unknown method is an error naming the valid ones
  if (config.contains("method") && config["method"] != method)
    throw ConfigError("/method",
                      "is " + config["method"].dump() + " in " + source + " but the method asked for is " + method);
  config["method"] = method;
}

}  // namespace relit::method
