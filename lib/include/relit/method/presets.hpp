// The preset run configs and loading a run config (docs/method.md, "Presets"; docs/config.md lists every key).
//
//   Json config = relit::method::load_run_config("fast");               // a preset, or the path of a .json file
//   relit::method::set_method(config, "nerv", "fast");                  // or choose a baseline's preset:
//   Json nerv = relit::method::load_run_config(relit::method::config_for_method("fast", "nerv"));  // "nerv-fast"
#pragma once

#include <relit/config.hpp>

#include <string>
#include <vector>

namespace relit::method {

/// The names of the preset configs ("fast", "paper", and per baseline "bi-fast", "nerv-paper", ...).
std::vector<std::string> preset_names();
/// A preset run config by name; throws InvalidArgument listing the presets for an unknown name.
Json preset(const std::string& name);
/// The preset or file to load for `spec` and a method: with a preset name ("fast", "paper") and a baseline
/// method ("bi", "nerv"), that method's preset ("bi-fast"); otherwise `spec` itself. Throws InvalidArgument
/// for an unknown method.
std::string config_for_method(const std::string& spec, const std::string& method);
/// Sets a run config's "method" to `method` (nothing when empty): a config that names another method is a
/// ConfigError naming `source` (where the config came from), an unknown method an InvalidArgument.
void set_method(Json& config, const std::string& method, const std::string& source);
/// `spec` is a preset name or the path of a JSON file; throws ConfigError/IOError naming the file on errors.
Json load_run_config(const std::string& spec);

}  // namespace relit::method
