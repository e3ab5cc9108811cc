// Top-level command line: global options, subcommand registry, error reporting.
#include "cli.hpp"

#include <relit/error.hpp>
#include <relit/log.hpp>
#include <relit/version.hpp>

#include <iostream>

namespace relit::cli {

int run(const std::vector<std::string>& args) {
  CLI::App app{"relit: neural relightable participating media on OpenCL", "relit"};
  app.set_version_flag("--version", std::string("relit ") + relit::version() + " (OpenCL C 1.2 kernels)");
  app.require_subcommand(1);
  std::string log_level;
  app.add_option("--log", log_level, "log level: debug, info, warning, error, off (default: $RELIT_LOG or info)")
      ->check(CLI::IsMember({"debug", "info", "warning", "error", "off"}, CLI::ignore_case));
  app.parse_complete_callback([&] {
    if (!log_level.empty()) set_log_level(parse_log_level(log_level));
  });
  add_devices_command(app);
  add_config_reference_command(app);
  add_generate_command(app);
  add_train_command(app);
  add_render_command(app);
  add_eval_command(app);
  add_demo_command(app);
  add_bench_command(app);

  std::vector<std::string> reversed(args.rbegin(), args.rend() - (args.empty() ? 0 : 1));
  try {
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const relit::Error& e) {
    std::cerr << "relit: error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}

}  // namespace relit::cli
