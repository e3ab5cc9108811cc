// Fuzz target: a dataset's transforms file (transforms_train.json), read with the images it names as the
// trainer reads a split (load_split). The dataset folder also holds r_0.png (2x2 RGB), r_1.exr (2x2 RGBA)
// and env.exr, which an input may name as its frames' file_path or its environment's file.
#include <relit/dataset.hpp>
#include <relit/io/image.hpp>

#include "fuzz_common.hpp"

#include <filesystem>

namespace {
const std::filesystem::path& dataset_dir() {
  static const std::filesystem::path dir = [] {
    const auto d = relit::fuzz::scratch_dir() / "dataset";
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  relit::write_image((dataset_dir() / "r_0.png").string(), relit::Image(2, 2, 3, 0.25f));
  relit::write_image((dataset_dir() / "r_1.exr").string(), relit::Image(2, 2, 4, 0.5f));
  relit::write_image((dataset_dir() / "env.exr").string(), relit::Image(8, 4, 3, 1.0f));
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  relit::fuzz::write_input("dataset/transforms_train.json", data, size);
  return relit::fuzz::expect_only_relit_errors([&] { relit::load_split(dataset_dir().string(), "train"); });
}
