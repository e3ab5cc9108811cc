// Fuzz target: a scene file (Scene::load). Next to it lie env.exr and env.hdr, small environment maps an
// input may name as its "file".
#include <relit/io/image.hpp>
#include <relit/scene/scene.hpp>

#include "fuzz_common.hpp"

#include <filesystem>

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const relit::Image env(8, 4, 3, 0.5f);
  relit::write_image((relit::fuzz::scratch_dir() / "env.exr").string(), env);
  relit::write_image((relit::fuzz::scratch_dir() / "env.hdr").string(), env);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = relit::fuzz::write_input("scene.json", data, size);
  return relit::fuzz::expect_only_relit_errors([&] { relit::Scene::load(path); });
}
