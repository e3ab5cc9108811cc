// The relit command-line interface, callable from main() and from the Python module.
#pragma once

#include <CLI/CLI.hpp>

#include <cmath>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace relit::cli {

/// Runs the command line `args` (args[0] is the program name) and returns the process exit code.
/// Errors are printed to stderr as "relit: error: ..." and give exit code 1 (2 for usage errors).
int run(const std::vector<std::string>& args);

/// An option check: an integer in [lo, hi], written in decimal ("-5", "1e3" and "4294967296" for a 32-bit
/// option are refused with the valid range, never wrapped or ignored).
inline CLI::Validator integer_in(long long lo, long long hi) {
  const std::string range = "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
  return CLI::Validator(
      [lo, hi, range](std::string& text) {
        long long v = 0;
        std::size_t used = 0;
        try {
          v = std::stoll(text, &used, 10);
        } catch (const std::exception&) {
          used = 0;
        }
        if (used == text.size() && !text.empty() && v >= lo && v <= hi) return std::string();
        return "must be an integer in " + range + ", got " + text;
      },
      range);
}

/// An integer of at least `min` (up to the 32-bit range).
inline CLI::Validator at_least(long long min) { return integer_in(min, 4294967295LL); }

/// An option check: a finite number in [lo, hi] ("nan", "inf" and "1e999" are refused).
inline CLI::Validator number_in(double lo, double hi) {
  std::ostringstream r;
  r << "[" << lo << ", " << hi << "]";
  const std::string range = r.str();
  return CLI::Validator(
      [lo, hi, range](std::string& text) {
        double v = 0;
        std::size_t used = 0;
        try {
          v = std::stod(text, &used);
        } catch (const std::exception&) {
          used = 0;
        }
        if (used == text.size() && !text.empty() && std::isfinite(v) && v >= lo && v <= hi) return std::string();
        return "must be a finite number in " + range + ", got " + text;
      },
      range);
}

/// The `--device` option every device command has.
inline void add_device_option(CLI::App* cmd, std::string& device) {
  cmd->add_option("--device,-d", device, "OpenCL device selector (index, platform:device, or name part)");
}

/// Runs `run(*options)` once the command line is parsed; a non-zero result becomes the exit code.
template <class Options, class Run>
void on_parsed(CLI::App* cmd, std::shared_ptr<Options> options, Run run) {
  cmd->final_callback([options, run] {
    if (const int code = run(*options)) throw CLI::RuntimeError(code);
  });
}

// Each subcommand registers itself on the app; add new ones in cli.cpp.
void add_devices_command(CLI::App& app);
void add_config_reference_command(CLI::App& app);
void add_generate_command(CLI::App& app);
void add_train_command(CLI::App& app);
void add_render_command(CLI::App& app);
void add_export_command(CLI::App& app);
void add_eval_command(CLI::App& app);
void add_demo_command(CLI::App& app);
void add_bench_command(CLI::App& app);

}  // namespace relit::cli
