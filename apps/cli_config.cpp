// relit config-reference: prints (or writes) the generated configuration reference, docs/config.md.
#include "cli.hpp"

#include <relit/config_reference.hpp>
#include <relit/io/file.hpp>

#include <iostream>

namespace relit::cli {

void add_config_reference_command(CLI::App& app) {
  auto output = std::make_shared<std::string>();
  auto* cmd = app.add_subcommand("config-reference", "print the configuration reference (Markdown) of every component");
  cmd->add_option("--output,-o", *output, "write it to this file instead of stdout (e.g. docs/config.md)");
  cmd->final_callback([output] {
    const std::string text = config_reference_markdown();
    if (output->empty()) {
      std::cout << text;
      return;
    }
    io::write_file_atomic(*output, text);  // an interrupted write never leaves half a file
  });
}

}  // namespace relit::cli
