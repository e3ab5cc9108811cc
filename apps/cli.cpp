// Top-level command line: global options, subcommand registry, error reporting.
#include "cli.hpp"

#include <relit/error.hpp>
#include <relit/log.hpp>
#include <relit/parallel.hpp>
#include <relit/version.hpp>

#include <cstdlib>
#include <filesystem>
#include <iostream>

namespace relit::cli {

int run(const std::vector<std::string>& args) {
  CLI::App app{"relit: neural relightable participating media on OpenCL", "relit"};
  app.set_version_flag("--version", std::string("relit ") + relit::version() + " (OpenCL C 1.2 kernels; " +
                                        relit::build_features() + ")");
  app.require_subcommand(1);
  // Usage errors read like every other error and say where to look (set before the subcommands inherit it).
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return "relit: error: " + std::string(e.what()) + "\nRun 'relit COMMAND --help' for the options of a command.\n";
  });
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
  add_export_command(app);
  add_eval_command(app);
  add_demo_command(app);
  add_bench_command(app);

  // An unknown command is named as such (CLI11 would say "A subcommand is required" or list extras).
  std::string names;
  bool known = false;
  for (const auto* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
    names += (names.empty() ? "" : ", ") + sub->get_name();
    known |= args.size() > 1 && sub->check_name(args[1]);
  }
  if (args.size() > 1 && !args[1].empty() && args[1][0] != '-' && !known) {
    std::cerr << "relit: error: unknown command '" << args[1] << "'; the commands are " << names
              << " (relit --help says what each does)\n";
    return 2;
  }
  // The error boundary: whatever is thrown below ends here with a message and a non-zero exit, never an abort.
  std::vector<std::string> reversed(args.rbegin(), args.rend() - (args.empty() ? 0 : 1));
  try {
    if (const char* env = std::getenv("RELIT_LOG"); env && *env) {
      try {
        set_log_level(parse_log_level(env));
      } catch (const InvalidArgument& e) {
        throw InvalidArgument(std::string("RELIT_LOG='") + env + "': " + e.what());
      }
    }
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    // --help and --version: 0; a command's own exit code (CLI::RuntimeError) as it is; every usage error: 2.
    const int code = app.exit(e);
    return code == 0 || dynamic_cast<const CLI::RuntimeError*>(&e) ? code : 2;
  } catch (const relit::Error& e) {
    std::cerr << "relit: error: " << parallel::rank_prefix() << e.what() << '\n';
    return 1;
  } catch (const std::filesystem::filesystem_error& e) {
    std::cerr << "relit: error: " << parallel::rank_prefix() << e.code().message() << ": '" << e.path1().string() << "'"
              << (e.path2().empty() ? "" : " → '" + e.path2().string() + "'") << '\n';
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "relit: error: " << parallel::rank_prefix()
              << "out of host memory (use a smaller resolution, batch or view count)\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "relit: error: " << parallel::rank_prefix() << e.what()
              << " (an unexpected error: please report it)\n";
    return 1;
  } catch (...) {
    std::cerr << "relit: error: an unknown exception (please report it)\n";
    return 1;
  }
  return 0;
}

}  // namespace relit::cli
