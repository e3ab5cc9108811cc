// Comparing two folders of images (relit eval --predictions DIR --references DIR): pairs by relative path, the
// metrics of every pair, the report's views.
#include <relit/dataset.hpp>
#include <relit/error.hpp>
#include <relit/log.hpp>
#include <relit/report.hpp>

#include "shared.hpp"

#include <algorithm>
#include <filesystem>
#include <map>
#include <set>

namespace fs = std::filesystem;

namespace relit::report {

namespace {

using ::relit::detail::lower;

// Image formats by preference when one name has several (relit eval writes r_000.png and r_000.exr): the float
// formats first, as the PNGs are 8-bit sRGB previews.
constexpr const char* kFormats[] = {".exr", ".pfm", ".hdr", ".png", ".jpg", ".jpeg"};

int rank_of(const std::string& ext) {
  for (int i = 0; i < int(std::size(kFormats)); ++i)
    if (ext == kFormats[i]) return i;
  return -1;
}

// split/stem → file, for every image under `dir` (the split: the folder it lies in relative to `dir`, '/' → '_',
// "images" for the top level).
std::map<std::string, std::string> images_under(const std::string& dir, const char* what) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw IOError(std::string(what) + " folder " + dir + " does not exist or is not a folder");
  std::map<std::string, std::pair<int, std::string>> best;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    if (!it->is_regular_file(ec)) continue;
    const fs::path& p = it->path();
    const int r = rank_of(lower(p.extension().string()));
    if (r < 0 || p.filename().string().front() == '.') continue;  // not an image; a temporary or hidden file
    const fs::path rel = fs::relative(p, dir, ec).parent_path();
    std::string split = rel.empty() ? "images" : rel.generic_string();
    std::replace(split.begin(), split.end(), '/', '_');
    const std::string key = split + "/" + p.stem().string();
    auto found = best.find(key);
    if (found == best.end() || r < found->second.first) best[key] = {r, p.string()};
  }
  if (ec) throw IOError(std::string("cannot list the ") + what + " folder " + dir + ": " + ec.message());
  std::map<std::string, std::string> out;
  for (const auto& [key, entry] : best) out[key] = entry.second;
  return out;
}

// A dataset folder (transforms_<split>.json): its frames' images by split/stem, in the dataset's order.
std::vector<std::pair<std::string, std::string>> dataset_images(const std::string& dir) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& [split, frames] : read_dataset(dir).splits)
    for (const auto& f : frames)
      out.emplace_back(split + "/" + fs::path(f.file_path).stem().string(), (fs::path(dir) / f.file_path).string());
  return out;
}

// The split of a key "split/stem".
std::string split_of(const std::string& key) { return key.substr(0, key.find('/')); }

bool is_dataset(const std::string& dir) {
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("transforms_", 0) == 0 && it->path().extension() == ".json") return true;
  }
  return false;
}

Image read_rgb_image(const std::string& path) {
  Image img = read_image(path);
  if (img.channels < 3)
    throw IOError(path + ": expected an RGB(A) image, it has " + std::to_string(img.channels) + " channel" +
                  (img.channels == 1 ? "" : "s"));
  return img;
}

}  // namespace

FolderComparison compare_folders(const Device& device, const std::string& predictions, const std::string& references,
                                 const std::vector<std::string>& splits, const ProgressCallback& progress) {
  const auto left_out = [&](const auto& entry) {
    return !splits.empty() && std::find(splits.begin(), splits.end(), split_of(entry.first)) == splits.end();
  };
  auto predicted = images_under(predictions, "predictions");
  for (auto it = predicted.begin(); it != predicted.end();) it = left_out(*it) ? predicted.erase(it) : std::next(it);
  std::vector<std::pair<std::string, std::string>> refs;
  if (is_dataset(references)) {
    refs = dataset_images(references);
  } else {
    for (const auto& entry : images_under(references, "references")) refs.push_back(entry);
  }
  if (refs.empty())
    throw IOError("the references folder " + references + " holds no images (.exr, .pfm, .hdr, .png, .jpg)");
  refs.erase(std::remove_if(refs.begin(), refs.end(), left_out), refs.end());
  for (const auto& split : splits)
    if (std::none_of(refs.begin(), refs.end(), [&](const auto& r) { return split_of(r.first) == split; }))
      throw IOError("the references folder " + references + " holds no image of the split '" + split + "'");
  std::vector<std::string> missing;
  for (const auto& [key, path] : refs)
    if (!predicted.count(key)) missing.push_back(key);
  if (!missing.empty()) {
    std::string list;
    for (std::size_t i = 0; i < missing.size() && i < 5; ++i) list += (i ? ", " : "") + missing[i];
    if (missing.size() > 5) list += ", ...";
    throw IOError(std::to_string(missing.size()) + " of the " + std::to_string(refs.size()) + " references have no " +
                  "prediction in " + predictions + " (" + list + "); a prediction is found by the reference's split " +
                  "folder and file name, any image extension (test/r_000.exr for test/r_000.png)");
  }
  FolderComparison out;
  std::set<std::string> referenced;
  ProgressTracker tracker(progress, refs.size(), "views");
  for (const auto& [key, ref_path] : refs) {
    const std::string& pred_path = predicted.at(key);
    referenced.insert(key);
    const Image ref = read_rgb_image(ref_path), pred = read_rgb_image(pred_path);
    if (ref.width != pred.width || ref.height != pred.height)
      throw IOError(pred_path + " is " + std::to_string(pred.width) + "x" + std::to_string(pred.height) +
                    " but its reference " + ref_path + " is " + std::to_string(ref.width) + "x" +
                    std::to_string(ref.height));
    ViewResult v;
    v.split = split_of(key);
    v.name = key.substr(key.find('/') + 1);
    v.width = std::uint32_t(ref.width);
    v.height = std::uint32_t(ref.height);
    auto [ref_rgb, ref_alpha] = split_rgb_alpha(ref);
    auto [pred_rgb, pred_alpha] = split_rgb_alpha(pred);
    v.prediction = std::move(pred_rgb);
    v.reference = std::move(ref_rgb);
    for (const auto* img : {&v.prediction, &v.reference})
      for (float x : *img)
        if (!std::isfinite(x))
          throw IOError((img == &v.prediction ? pred_path : ref_path) + " holds a NaN or infinite value");
    const auto mask = metrics::object_mask(ref_alpha, pred_alpha, std::size_t(v.width) * v.height);
    v.prediction_alpha = std::move(pred_alpha);
    v.metrics = metrics::compare(device, v.prediction, v.reference, v.width, v.height, 3, &mask);
    out.views.push_back(std::move(v));
    tracker.update(out.views.size(), key);
  }
  for (const auto& [key, path] : predicted)
    if (!referenced.count(key)) out.unmatched_predictions.push_back(path);
  return out;
}

}  // namespace relit::report
