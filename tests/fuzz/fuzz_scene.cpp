// Fuzz target: a scene file (Scene::load). Next to it lie env.exr and env.hdr, small environment maps an
// input may name as its "file".
//
// What this target fuzzes is the reader, not the cost of the procedural generators it calls: a valid medium or
// solid source at resolution 64 (the default) to 512 takes seconds to minutes under the sanitizers, and would
// be reported as a hang. So a document that parses and asks for a source above resolution 16 (or gives none,
// which means 64) is read with that resolution set to 16; every other input reaches the reader byte for byte.
#include <relit/io/image.hpp>
#include <relit/scene/scene.hpp>

#include "fuzz_common.hpp"

#include <filesystem>

namespace {
constexpr int kMaxResolution = 16;

// Lowers the resolution of the medium's and the solid's source; true when it changed anything.
bool cap_resolutions(relit::Json& scene) {
  bool changed = false;
  for (const char* part : {"medium", "solid"}) {
    if (!scene.contains(part) || !scene[part].is_object()) continue;
    relit::Json& p = scene[part];
    if (!p.contains("source")) p["source"] = relit::Json::object();  // the default source, at resolution 64
    relit::Json& source = p["source"];
    if (!source.is_object()) continue;
    if (!source.contains("resolution") ||
        (source["resolution"].is_number() && source["resolution"].get<double>() > kMaxResolution)) {
      source["resolution"] = kMaxResolution;
      changed = true;
    }
  }
  return changed;
}
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const relit::Image env(8, 4, 3, 0.5f);
  relit::write_image((relit::fuzz::scratch_dir() / "env.exr").string(), env);
  relit::write_image((relit::fuzz::scratch_dir() / "env.hdr").string(), env);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  relit::Json scene = relit::Json::parse(data, data + size, nullptr, /*allow_exceptions=*/false);
  std::string path;
  if (scene.is_object() && cap_resolutions(scene)) {
    const std::string text = scene.dump();
    path = relit::fuzz::write_input("scene.json", reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
  } else {
    path = relit::fuzz::write_input("scene.json", data, size);
  }
  return relit::fuzz::expect_only_relit_errors([&] { relit::Scene::load(path); });
}
