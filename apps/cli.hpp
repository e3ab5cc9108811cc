// The relit command-line interface, callable from main() and from the Python module.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace relit::cli {

/// Runs the command line `args` (args[0] is the program name) and returns the process exit code.
/// Errors are printed to stderr as "relit: error: ..." and give exit code 1 (2 for usage errors).
int run(const std::vector<std::string>& args);

/// An option check: an integer of at least `min` (CLI11's Range names the type's whole range in its message).
inline CLI::Validator at_least(long long min) {
  const std::string bound = std::to_string(min);
  return CLI::Validator(
      [min, bound](std::string& text) {
        long long v = 0;
        if (CLI::detail::lexical_cast(text, v) && v >= min) return std::string();
        return "must be an integer of at least " + bound + ", got " + text;
      },
      ">=" + bound);
}

// Each subcommand registers itself on the app; add new ones in cli.cpp.
void add_devices_command(CLI::App& app);
void add_config_reference_command(CLI::App& app);
void add_generate_command(CLI::App& app);
void add_train_command(CLI::App& app);
void add_render_command(CLI::App& app);
void add_eval_command(CLI::App& app);
void add_demo_command(CLI::App& app);
void add_bench_command(CLI::App& app);

}  // namespace relit::cli
