// The relit command-line interface, callable from main() and from the Python module.
#pragma once

#include <CLI/CLI.hpp>

#include <string>
#include <vector>

namespace relit::cli {

/// Runs the command line `args` (args[0] is the program name) and returns the process exit code.
/// Errors are printed to stderr as "relit: error: ..." and give exit code 1 (2 for usage errors).
int run(const std::vector<std::string>& args);

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
