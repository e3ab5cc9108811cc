// Reading a dataset split back for training and evaluation: cameras, lights and linear RGB images
// (docs/dataset-format.md). The writer is dataset.cpp.
#include <relit/dataset.hpp>
#include <relit/io/image.hpp>

#include <cmath>
#include <filesystem>

namespace fs = std::filesystem;

namespace relit {

std::vector<float> DatasetSplit::image(std::size_t i) const {
  const std::size_t n = std::size_t(width) * height * 3;
  return std::vector<float>(images.begin() + i * n, images.begin() + (i + 1) * n);
}

std::vector<float> DatasetSplit::alpha(std::size_t i) const {
  if (alphas.empty()) return {};
  const std::size_t n = std::size_t(width) * height;
  return std::vector<float>(alphas.begin() + i * n, alphas.begin() + (i + 1) * n);
}

namespace {
// The "environment" entry of a transforms file: null, or {file, scale, visible} (docs/dataset-format.md).
std::shared_ptr<const EnvironmentLight> load_environment(const std::string& dataset_dir, const std::string& file,
                                                         const Json& env) {
  if (env.is_null()) return nullptr;
  const std::string where = (fs::path(dataset_dir) / file).string() + ": environment";
  if (!env.is_object() || !env.contains("file") || !env["file"].is_string())
    throw IOError(where + " must be null or {\"file\": ..., \"scale\": ..., \"visible\": ...}, got " + env.dump());
  const Json scale = env.value("scale", Json(1.0));
  const Json visible = env.value("visible", Json(false));
  if (!scale.is_number() || !std::isfinite(scale.get<double>()) || scale.get<double>() < 0)
    throw IOError(where + "/scale must be a finite number >= 0, got " + scale.dump());
  if (!visible.is_boolean()) throw IOError(where + "/visible must be true or false, got " + visible.dump());
  const fs::path rel = fs::path(env["file"].get<std::string>()).lexically_normal();
  if (rel.is_absolute() || rel.empty() || *rel.begin() == "..")
    throw IOError(where + "/file \"" + env["file"].get<std::string>() + "\" leaves the dataset folder");
  const std::string path = (fs::path(dataset_dir) / rel).string();
  return std::make_shared<const EnvironmentLight>(read_image(path), scale.get<float>(), visible.get<bool>(), path);
}
}  // namespace

DatasetSplit load_split(const std::string& dataset_dir, const std::string& split, std::size_t max_views) {
  const DatasetDescription desc = read_dataset(dataset_dir);
  auto it = desc.splits.find(split);
  if (it == desc.splits.end() || it->second.empty()) {
    std::string have;
    for (const auto& [k, v] : desc.splits) have += (have.empty() ? "" : ", ") + k;
    throw IOError("dataset " + dataset_dir + " has no '" + split + "' views (splits: " + have + ")");
  }
  const auto& frames = it->second;
  std::vector<std::size_t> picks;
  const std::size_t n = max_views && max_views < frames.size() ? max_views : frames.size();
  for (std::size_t k = 0; k < n; ++k) picks.push_back(k * frames.size() / n);
  DatasetSplit out;
  out.split = split;
  for (std::size_t k : picks) {
    const auto& f = frames[k];
    const std::string path = (fs::path(dataset_dir) / f.file_path).string();
    const Image img = read_image(path);
    if (img.channels < 3)
      throw IOError(path + ": expected an RGB(A) image, it has " + std::to_string(img.channels) + " channels");
    if (img.width != f.camera.width || img.height != f.camera.height)
      throw IOError(path + ": the image is " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                    " but its camera says " + std::to_string(f.camera.width) + "x" + std::to_string(f.camera.height));
    if (out.cameras.empty()) {
      out.width = img.width;
      out.height = img.height;
    } else if (img.width != out.width || img.height != out.height) {
      throw IOError(path + ": all images of a split must have the same size");
    }
    for (std::size_t p = 0; p < std::size_t(img.width) * img.height; ++p)
      for (int c = 0; c < 3; ++c) {
        const float v = img.pixels[p * img.channels + c];
        if (!std::isfinite(v) || v < 0)
          throw IOError(path + ": pixel (" + std::to_string(p % img.width) + ", " + std::to_string(p / img.width) +
                        ") channel " + std::to_string(c) + " is " + std::to_string(v) +
                        "; radiance must be finite and >= 0");
        out.images.push_back(v);
      }
    // The alpha of RGBA images (1 - transmittance: the object's coverage); an RGB image makes the split's unknown.
    if (img.channels >= 4 && (out.cameras.empty() || !out.alphas.empty()))
      for (std::size_t p = 0; p < std::size_t(img.width) * img.height; ++p)
        out.alphas.push_back(img.pixels[p * img.channels + 3]);
    else
      out.alphas.clear();
    out.names.push_back(fs::path(f.file_path).stem().string());
    out.cameras.push_back(f.camera);
    out.lights.push_back(f.light);
  }
  out.environment = load_environment(dataset_dir, "transforms_" + split + ".json", desc.environment);
  return out;
}

std::shared_ptr<const EnvironmentLight> dataset_environment(const std::string& dataset_dir) {
  return load_environment(dataset_dir, "transforms_*.json", read_dataset(dataset_dir).environment);
}

}  // namespace relit
