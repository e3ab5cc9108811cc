// Fuzz target: a run config file, read as `relit train --config FILE` reads it (load_run_config), then checked
// key by key as the Trainer does (check_run_config: method, model and training sections, no device).
#include <relit/method/presets.hpp>
#include <relit/method/trainer.hpp>

#include "fuzz_common.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = relit::fuzz::write_input("config.json", data, size);
  return relit::fuzz::expect_only_relit_errors([&] {
    const relit::Json config = relit::method::load_run_config(path);
    relit::method::check_run_config(config);
  });
}
