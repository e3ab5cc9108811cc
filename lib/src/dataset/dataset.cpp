// Dataset generation: view planning, rendering through the reference path tracer, atomic folder writes.
#include <relit/dataset.hpp>
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/io/image.hpp>
#include <relit/log.hpp>
#include <relit/parallel.hpp>
#include <relit/version.hpp>

#include "shared.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <unistd.h>

namespace fs = std::filesystem;

namespace relit {

namespace {

using ::relit::detail::kPi;

Float3 unit_from(double u1, double u2) {
  const double z = 1 - 2 * u1, r = std::sqrt(std::max(0.0, 1 - z * z)), phi = 2 * kPi * u2;
  return {float(r * std::cos(phi)), float(r * std::sin(phi)), float(z)};
}

Float3 scaled(const Float3& v, double s) { return {float(v[0] * s), float(v[1] * s), float(v[2] * s)}; }

Camera camera_at(const Float3& dir, const DatasetSettings& s) {
  // Up is +z unless the camera looks almost straight down or up.
  const Float3 up = std::abs(dir[2]) > 0.999f ? Float3{0, 1, 0} : Float3{0, 0, 1};
  return Camera::look_at(scaled(dir, s.camera_distance), {0, 0, 0}, up, s.camera_angle_x, s.resolution, s.resolution);
}

// A stream per purpose, so that e.g. adding validation views never changes the training lights.
std::mt19937_64 stream(std::uint32_t seed, std::uint32_t purpose) {
  std::seed_seq seq{seed, purpose, 0x5EEDu};
  return std::mt19937_64(seq);
}

std::string frame_name(const std::string& split, std::size_t i) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "r_%03zu", i);
  return split + "/" + buf;
}

Json vec_json(const Float3& v) { return Json::array({v[0], v[1], v[2]}); }

}  // namespace

std::uint32_t dataset_view_seed(std::uint32_t seed, const std::string& split, std::size_t i) {
  std::uint32_t h = seed * 0x9E3779B9u ^ std::uint32_t(i) * 0x85EBCA6Bu;
  for (char c : split) h = (h ^ std::uint8_t(c)) * 0x01000193u;
  return h;
}

void DatasetSettings::validate() const {
  if (lighting != "point" && lighting != "env+point")
    throw InvalidArgument("lighting must be 'point' or 'env+point', got '" + lighting + "'");
  if (resolution < 4 || resolution > 4096) throw InvalidArgument("resolution must lie in [4, 4096]");
  if (train + val + test == 0) throw InvalidArgument("the dataset needs at least one view (train, val or test)");
  if (train > 100000 || val > 100000 || test > 100000) throw InvalidArgument("more than 100000 views in a split");
  if (spp < 1 || spp > 65536) throw InvalidArgument("spp must lie in [1, 65536]");
  if (test_spp > 65536) throw InvalidArgument("test_spp must lie in [0, 65536] (0: the same as spp)");
  if (!(camera_distance > 1.8f) || !std::isfinite(camera_distance))
    throw InvalidArgument("camera_distance must exceed 1.8 (cameras stay outside the scene box [-1, 1]^3)");
  if (!(camera_angle_x > 0.05f && camera_angle_x < 3.0f)) throw InvalidArgument("camera_angle_x must lie in (0.05, 3)");
  if (!(light_distance_min > 1.8f) || !(light_distance_max >= light_distance_min) || !std::isfinite(light_distance_max))
    throw InvalidArgument("light distances must satisfy 1.8 < min <= max (lights stay outside the scene box)");
  if (!(intensity_min >= 0) || !(intensity_max >= intensity_min) || !std::isfinite(intensity_max))
    throw InvalidArgument("light intensities must satisfy 0 <= min <= max, got [" + std::to_string(intensity_min) +
                          ", " + std::to_string(intensity_max) + "]");
  if (!(env_scale >= 0) || !std::isfinite(env_scale)) throw InvalidArgument("env_scale must be finite and >= 0");
  if (generalization && generalization_views == 0) throw InvalidArgument("generalization_views must be >= 1");
  if (!(generalization_intensity > 0) || !(generalization_intensity <= 1e9f))
    throw InvalidArgument("generalization_intensity must be in (0, 1e9] W/sr, got " +
                          std::to_string(generalization_intensity));
}

std::vector<int> generalization_intensities(float base_intensity) {
  std::vector<int> out;
  for (int k : {2, 4, 6, 8}) out.push_back(int(std::lround(double(base_intensity) * k / 3.0)));
  return out;
}

DatasetDescription plan_dataset(const DatasetSettings& s) {
  s.validate();
  DatasetDescription d;
  d.lighting = s.lighting;
  auto intensity_of = [&](double u) { return float(s.intensity_min + (s.intensity_max - s.intensity_min) * u); };
  auto light_of = [](const Float3& dir, double dist, float intensity) {
    PointLight l;
    l.position = scaled(dir, dist);
    l.intensity = {intensity, intensity, intensity};
    return l;
  };
  std::uniform_real_distribution<double> u(0.0, 1.0);

  // Training: a Fibonacci sphere under a random rotation; light distances and intensities stratified.
  {
    auto rng = stream(s.seed, 1);
    const double a = u(rng) * 2 * kPi, b = std::acos(1 - 2 * u(rng)), c = u(rng) * 2 * kPi;
    const double ca = std::cos(a), sa = std::sin(a), cb = std::cos(b), sb = std::sin(b), cc = std::cos(c),
                 sc = std::sin(c);
    const double R[3][3] = {{ca * cc - sa * cb * sc, -ca * sc - sa * cb * cc, sa * sb},
                            {sa * cc + ca * cb * sc, -sa * sc + ca * cb * cc, -ca * sb},
                            {sb * sc, sb * cc, cb}};
    std::vector<std::size_t> perm_d(s.train), perm_i(s.train);
    std::iota(perm_d.begin(), perm_d.end(), 0);
    std::iota(perm_i.begin(), perm_i.end(), 0);
    std::shuffle(perm_d.begin(), perm_d.end(), rng);
    std::shuffle(perm_i.begin(), perm_i.end(), rng);
    auto& frames = d.splits["train"];
    for (std::uint32_t i = 0; i < s.train; ++i) {
      const double z = 1 - (2.0 * i + 1) / s.train, r = std::sqrt(std::max(0.0, 1 - z * z));
      const double phi = i * kPi * (3 - std::sqrt(5.0));
      const double p[3] = {r * std::cos(phi), r * std::sin(phi), z};
      Float3 dir;
      for (int k = 0; k < 3; ++k) dir[k] = float(R[k][0] * p[0] + R[k][1] * p[1] + R[k][2] * p[2]);
      const Float3 ldir = unit_from(u(rng), u(rng));
      const double dist =
          s.light_distance_min + (s.light_distance_max - s.light_distance_min) * (perm_d[i] + u(rng)) / s.train;
      frames.push_back({frame_name("train", i) + ".exr", camera_at(dir, s),
                        light_of(ldir, dist, intensity_of((perm_i[i] + u(rng)) / s.train))});
    }
  }
  // Validation and test: independent random cameras and lights.
  for (const auto& [name, count, purpose] :
       {std::make_tuple(std::string("val"), s.val, 2u), std::make_tuple(std::string("test"), s.test, 3u)}) {
    auto rng = stream(s.seed, purpose);
    auto& frames = d.splits[name];
    for (std::uint32_t i = 0; i < count; ++i) {
      const Float3 dir = unit_from(u(rng), u(rng));
      const Float3 ldir = unit_from(u(rng), u(rng));
      const double dist = s.light_distance_min + (s.light_distance_max - s.light_distance_min) * u(rng);
      frames.push_back({frame_name(name, i) + ".exr", camera_at(dir, s), light_of(ldir, dist, intensity_of(u(rng)))});
    }
  }
  // Generalisation studies (appendix H): the same cameras and light directions, one varying factor.
  if (s.generalization) {
    auto rng = stream(s.seed, 4);
    std::vector<std::pair<Float3, Float3>> views;
    for (std::uint32_t i = 0; i < s.generalization_views; ++i)
      views.push_back({unit_from(u(rng), u(rng)), unit_from(u(rng), u(rng))});
    // generalization_intensity is the distance sets' intensity and the unit of the intensity sets: 2/3, 4/3, 2
    // and 8/3 of it (the paper's 400, 800, 1200, 1600 W/sr for the default 600), named by their values.
    const float base = s.generalization_intensity;
    for (int dist : {3, 5, 7, 10}) {
      const std::string name = "test_distance_" + std::to_string(dist);
      for (std::size_t i = 0; i < views.size(); ++i)
        d.splits[name].push_back(
            {frame_name(name, i) + ".exr", camera_at(views[i].first, s), light_of(views[i].second, dist, base)});
    }
    for (int inten : generalization_intensities(base)) {
      const std::string name = "test_intensity_" + std::to_string(inten);
      for (std::size_t i = 0; i < views.size(); ++i)
        d.splits[name].push_back(
            {frame_name(name, i) + ".exr", camera_at(views[i].first, s), light_of(views[i].second, 4.0, float(inten))});
    }
  }
  return d;
}

namespace {

// --overwrite replaces only what relit wrote: a folder with a scene.json and transforms_*.json files that
// carry "relit_version", and besides them only the split folders of those files holding images. Anything
// else (a home folder, a file, a dataset with the user's own files added) is refused before any work.
void check_replaceable_dataset(const fs::path& out) {
  const std::string named = "--overwrite: '" + out.string() + "'";
  std::error_code ec;
  if (!fs::is_directory(out, ec))
    throw IOError(named + " is a file, not a dataset folder; relit replaces only a dataset it wrote");
  std::vector<std::string> splits, foreign;
  bool scene = false;
  for (fs::directory_iterator it(out, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("transforms_", 0) == 0 && it->path().extension() == ".json" && it->is_regular_file()) {
      Json doc;
      try {
        doc = parse_json(io::read_file(it->path().string()), name);
      } catch (const Error&) {}
      if (doc.is_object() && doc.contains("relit_version")) {
        splits.push_back(name.substr(11, name.size() - 16));
        continue;
      }
    } else if ((name == "scene.json" || name == "environment.exr") && it->is_regular_file()) {
      scene |= name == "scene.json";
      continue;
    } else if (it->is_directory()) {
      continue;  // checked below against the splits
    }
    foreign.push_back(name);
  }
  if (ec) throw IOError("cannot read " + named + ": " + ec.message());
  if (!scene || splits.empty())
    throw IOError(named +
                  " is not a dataset relit wrote (no scene.json and transforms_*.json by relit); it is "
                  "left untouched. Choose another --out, or remove it yourself");
  for (fs::directory_iterator it(out, ec), end; !ec && it != end; it.increment(ec)) {
    if (!it->is_directory()) continue;
    const std::string name = it->path().filename().string();
    if (std::find(splits.begin(), splits.end(), name) == splits.end()) {
      foreign.push_back(name + "/");
      continue;
    }
    for (const auto& f : fs::directory_iterator(it->path(), ec)) {
      const std::string ext = f.path().extension().string();
      if (!f.is_regular_file() || (ext != ".exr" && ext != ".png"))
        foreign.push_back(name + "/" + f.path().filename().string());
    }
  }
  if (!foreign.empty()) {
    std::string list;
    for (std::size_t i = 0; i < foreign.size() && i < 5; ++i) list += (i ? ", " : "") + foreign[i];
    if (foreign.size() > 5) list += ", ...";
    throw IOError(named + " holds files relit did not write (" + list +
                  "); it is left untouched. Move them out or choose another --out");
  }
}

}  // namespace

void generate_dataset(const Device& device, const Scene& input_scene, const std::string& out_dir,
                      const DatasetSettings& s, const ProgressCallback& progress) {
  s.validate();
  const fs::path out = fs::path(out_dir).lexically_normal();
  if (out.empty()) throw InvalidArgument("the output folder is empty");
  // Under MPI the views are shared out over the ranks (relit/parallel.hpp); rank 0 alone checks the output
  // folder and writes, in the single-process order, so the files are the same bytes whatever the ranks.
  const bool writer = parallel::rank() == 0;
  const fs::path parent = out.has_parent_path() ? out.parent_path() : fs::path(".");
  bool exists = false;
  if (writer) {
    std::error_code ec;
    exists = fs::exists(fs::symlink_status(out, ec));
    if (ec && ec != std::errc::no_such_file_or_directory)
      throw IOError("cannot use output folder '" + out.string() + "': " + ec.message());
    if (exists && !s.overwrite)
      throw IOError("output folder '" + out.string() +
                    "' already exists; choose another --out or pass --overwrite "
                    "(the existing folder is left untouched)");
    if (exists) check_replaceable_dataset(out);
    if (!fs::is_directory(parent, ec)) throw IOError("the parent folder of '" + out.string() + "' does not exist");
    if (::access(parent.c_str(), W_OK | X_OK) != 0)
      throw IOError("cannot write into '" + parent.string() +
                    "', the parent folder of the dataset: " + std::strerror(errno));
    io::remove_stale_temporaries(parent.string());  // what killed runs left behind
  }

  Scene scene = input_scene;
  Json scene_json = scene.description;
  Json env_json;  // null for 'point'
  if (s.lighting == "env+point") {
    if (!scene.environment) scene.environment = EnvironmentLight::sky(256, 128, s.seed, s.env_scale, s.env_visible);
  } else {
    scene.environment.reset();  // 'point': the point light alone
    scene_json.erase("environment");
  }
  scene_json.erase("lights");  // the per-view lights are in the transforms files
  scene_json.erase("cameras");

  const DatasetDescription plan = plan_dataset(s);
  auto split_spp = [&](const std::string& name) {
    return (name == "test" || name.rfind("test_", 0) == 0) && s.test_spp ? s.test_spp : s.spp;
  };
  // Every view in order, split by split, with the samples of the views before it (for the progress).
  struct View {
    const std::string* split;
    std::size_t index;
    std::uint64_t samples_before;
  };
  std::vector<View> views;
  std::uint64_t total = 0;
  for (const auto& [name, frames] : plan.splits)
    for (std::size_t i = 0; i < frames.size(); ++i) {
      views.push_back({&name, i, total});
      total += std::uint64_t(s.resolution) * s.resolution * split_spp(name);
    }
  ProgressTracker tracker(writer ? progress : ProgressCallback(), total, "samples");

  const PathTracer pt(device, scene);
  // One view, path-traced: its RGBA pixels.
  const auto render = [&](std::size_t v) {
    const View& view = views[v];
    const DatasetFrame& f = plan.splits.at(*view.split)[view.index];
    PathTraceSettings rs;
    rs.spp = split_spp(*view.split);
    rs.max_bounces = s.max_bounces;
    rs.seed = dataset_view_seed(s.seed, *view.split, view.index);
    ProgressCallback per_view;  // without a callback, launches run back to back with no waiting
    if (progress && writer)
      per_view = [&](const Progress& p) {
        tracker.update(view.samples_before + p.done, f.file_path.substr(0, f.file_path.size() - 4));
        return true;
      };
    return pt.render(f.camera, {f.light}, rs, per_view).image.pixels;
  };
  const auto view_size = [&](std::size_t) { return std::size_t(s.resolution) * s.resolution * 4; };  // RGBA
  if (!writer) {
    parallel::share_out(views.size(), view_size, render, {});
    return;
  }

  std::error_code ec;
  const fs::path tmp = parent / ("." + out.filename().string() + ".partial-" + std::to_string(::getpid()));
  if (!fs::create_directory(tmp, ec) || ec)
    throw IOError("cannot create the temporary folder '" + tmp.string() +
                  "': " + (ec ? ec.message() : std::string("it exists")));
  try {
    if (scene.environment) {
      write_image((tmp / "environment.exr").string(), scene.environment->image());
      env_json = {{"file", "environment.exr"},
                  {"scale", scene.environment->scale()},
                  {"visible", scene.environment->visible()}};
      scene_json["environment"] = env_json;
    }
    io::write_file_atomic((tmp / "scene.json").string(), scene_json.dump(2) + "\n");

    std::map<std::string, Json> docs;  // transforms_<split>.json, frame by frame
    for (const auto& [name, frames] : plan.splits) {
      if (frames.empty()) continue;
      fs::create_directories(tmp / name);
      docs[name] = {{"camera_angle_x", s.camera_angle_x},
                    {"w", s.resolution},
                    {"h", s.resolution},
                    {"lighting", s.lighting},
                    {"environment", env_json},
                    {"scene", "scene.json"},
                    {"spp", split_spp(name)},
                    {"seed", s.seed},
                    {"relit_version", relit::version()},
                    {"frames", Json::array()}};
    }
    const auto write_view = [&](std::size_t v, std::vector<float>&& pixels) {
      const View& view = views[v];
      const auto& frames = plan.splits.at(*view.split);
      const DatasetFrame& f = frames[view.index];
      Image image(s.resolution, s.resolution, 4);
      image.pixels = std::move(pixels);
      const std::string stem = f.file_path.substr(0, f.file_path.size() - 4);
      write_image((tmp / f.file_path).string(), image);
      if (s.previews) {
        Image rgb(image.width, image.height, 3);
        for (std::size_t p = 0; p < std::size_t(image.width) * image.height; ++p)
          for (int c = 0; c < 3; ++c) {
            const float x = std::max(image.pixels[p * 4 + c], 0.0f);
            rgb.pixels[p * 3 + c] = x / (1.0f + x);  // Reinhard: highlights stay readable in 8 bits
          }
        write_image((tmp / (stem + ".png")).string(), rgb);
      }
      Json m = Json::array();
      for (const auto& row : f.camera.transform) m.push_back(Json::array({row[0], row[1], row[2], row[3]}));
      Json frame = {
          {"file_path", f.file_path},
          {"transform_matrix", m},
          {"light",
           {{"type", "point"}, {"position", vec_json(f.light.position)}, {"intensity", vec_json(f.light.intensity)}}}};
      if (s.previews) frame["preview_path"] = stem + ".png";
      Json& doc = docs.at(*view.split);
      doc["frames"].push_back(frame);
      if (progress)
        tracker.update(
            view.samples_before + std::uint64_t(s.resolution) * s.resolution * doc["spp"].get<std::uint32_t>(), stem);
      if (view.index + 1 == frames.size())
        io::write_file_atomic((tmp / ("transforms_" + *view.split + ".json")).string(), doc.dump(2) + "\n");
    };
    parallel::share_out(views.size(), view_size, render, write_view);
    // Complete: move it into place. An existing folder is replaced only now, and only on request.
    if (exists) {
      // Checked again now that the render is done: the folder may have changed meanwhile.
      check_replaceable_dataset(out);
      const fs::path old = parent / ("." + out.filename().string() + ".old-" + std::to_string(::getpid()));
      io::rename_directory(out.string(), old.string());
      try {
        io::rename_directory(tmp.string(), out.string());
      } catch (...) {
        std::error_code restore;
        fs::rename(old, out, restore);  // put the old dataset back
        throw;
      }
      fs::remove_all(old, ec);
    } else {
      io::rename_directory(tmp.string(), out.string());
    }
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
  log_info("dataset written to " + out.string());
}

namespace {

// One transforms_<split>.json, checked key by key: every problem names the file, the frame and the key.
void read_transforms(const fs::path& file, const std::string& split, DatasetDescription& d, Json& environment) {
  const std::string where = "dataset file '" + file.string() + "'";
  const Json doc = parse_json(io::read_file(file.string()), where);
  auto bad = [&](const std::string& key, const std::string& why) { return IOError(where + ": " + key + " " + why); };
  if (!doc.is_object()) throw IOError(where + " must hold a JSON object");
  auto number = [&](const Json& obj, const char* key, const std::string& name) {
    if (!obj.contains(key) || !obj[key].is_number() || !std::isfinite(obj[key].get<double>()))
      throw bad(name, "must be a finite number");
    return obj[key].get<double>();
  };
  const double angle = number(doc, "camera_angle_x", "camera_angle_x");
  auto size = [&](const char* key) {
    if (!doc.contains(key) || !doc[key].is_number_integer() || doc[key].get<long long>() < 1 ||
        doc[key].get<long long>() > 16384)
      throw bad(key, std::string("must be the image ") + (key[0] == 'w' ? "width" : "height") +
                         " in pixels, an integer in [1, 16384]");
    return doc[key].get<int>();
  };
  const int w = size("w"), h = size("h");
  if (!doc.contains("lighting") || !doc["lighting"].is_string() ||
      (doc["lighting"] != "point" && doc["lighting"] != "env+point"))
    throw bad("lighting", "must be \"point\" or \"env+point\", got " +
                              (doc.contains("lighting") ? doc["lighting"].dump() : "nothing"));
  const std::string lighting = doc["lighting"].get<std::string>();
  if (!d.lighting.empty() && d.lighting != lighting)
    throw bad("lighting", "is \"" + lighting + "\" but another split of the dataset says \"" + d.lighting + "\"");
  d.lighting = lighting;
  const Json env = doc.contains("environment") ? doc["environment"] : Json();
  if (lighting == "env+point" && env.is_null()) throw bad("environment", "is required for lighting \"env+point\"");
  if (lighting == "point" && !env.is_null()) throw bad("environment", "must be null for lighting \"point\"");
  if (!environment.is_null() && env != environment)
    throw bad("environment", "differs from that of another split (" + environment.dump() + ")");
  environment = env;
  if (!doc.contains("frames") || !doc["frames"].is_array()) throw bad("frames", "must be an array of views");

  auto& frames = d.splits[split];
  for (std::size_t i = 0; i < doc["frames"].size(); ++i) {
    const Json& fr = doc["frames"][i];
    const std::string at = "frames[" + std::to_string(i) + "]";
    if (!fr.is_object()) throw bad(at, "must be an object");
    DatasetFrame frame;
    if (!fr.contains("file_path") || !fr["file_path"].is_string() || fr["file_path"].get<std::string>().empty())
      throw bad(at + ".file_path", "must be the image's path relative to the dataset folder");
    frame.file_path = fr["file_path"].get<std::string>();
    // The image must lie inside the dataset folder: "../../x" or "/etc/x" are refused, not followed.
    const fs::path rel = fs::path(frame.file_path).lexically_normal();
    if (rel.is_absolute() || rel.empty() || *rel.begin() == "..")
      throw bad(at + ".file_path", "\"" + frame.file_path + "\" leaves the dataset folder; give a path inside it");
    const std::string view = at + " (" + frame.file_path + ")";
    if (!fr.contains("transform_matrix") || !fr["transform_matrix"].is_array() || fr["transform_matrix"].size() != 4)
      throw bad(view + ".transform_matrix", "must be a 4x4 array of numbers");
    for (int r = 0; r < 4; ++r) {
      const Json& row = fr["transform_matrix"][r];
      if (!row.is_array() || row.size() != 4) throw bad(view + ".transform_matrix", "must be a 4x4 array of numbers");
      for (int c = 0; c < 4; ++c) {
        if (!row[c].is_number()) throw bad(view + ".transform_matrix", "must be a 4x4 array of numbers");
        frame.camera.transform[r][c] = row[c].get<float>();
      }
    }
    frame.camera.camera_angle_x = float(angle);
    frame.camera.width = w;
    frame.camera.height = h;
    try {
      frame.camera.validate();
    } catch (const InvalidArgument& e) {
      throw bad(view + ".transform_matrix", std::string("is not a usable camera: ") + e.what());
    }
    if (!fr.contains("light") || !fr["light"].is_object())
      throw bad(view + ".light", "is missing: every view needs its point light {type, position, intensity}");
    const Json& l = fr["light"];
    if (l.contains("type") && l["type"] != "point")
      throw bad(view + ".light.type", "must be \"point\", got " + l["type"].dump());
    for (const char* key : {"position", "intensity"}) {
      if (!l.contains(key) || !l[key].is_array() || l[key].size() != 3 || !l[key][0].is_number() ||
          !l[key][1].is_number() || !l[key][2].is_number())
        throw bad(view + ".light." + key, "must be an array of 3 numbers");
    }
    for (const auto& [key, target] : {std::pair<const char*, Float3*>{"position", &frame.light.position},
                                      std::pair<const char*, Float3*>{"intensity", &frame.light.intensity}})
      for (int k = 0; k < 3; ++k) (*target)[k] = l[key][k].get<float>();
    try {
      frame.light.validate();
    } catch (const InvalidArgument& e) {
      throw bad(view + ".light", std::string("is not usable: ") + e.what());
    }
    const std::set<std::string> known = {"type", "position", "intensity"};
    for (auto it = l.begin(); it != l.end(); ++it)
      if (!known.count(it.key()))
        throw bad(view + ".light." + it.key(), "is not a key of a point light (type, position, intensity)");
    frames.push_back(frame);
  }
}

}  // namespace

DatasetDescription read_dataset(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw IOError("dataset folder '" + dir + "' " +
                  (fs::exists(dir, ec) ? "is a file, not a folder" : std::string("does not exist")));
  // In name order, so that nothing depends on the order the file system lists the folder in.
  std::vector<fs::path> files;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string fname = it->path().filename().string();
    if (fname.rfind("transforms_", 0) == 0 && it->path().extension() == ".json") files.push_back(it->path());
  }
  if (ec) throw IOError("cannot read dataset folder '" + dir + "': " + ec.message());
  std::sort(files.begin(), files.end());
  DatasetDescription d;
  Json environment;
  for (const auto& file : files) {
    const std::string fname = file.filename().string();
    read_transforms(file, fname.substr(11, fname.size() - 11 - 5), d, environment);
  }
  d.environment = environment;
  if (d.splits.empty()) throw IOError("'" + dir + "' holds no transforms_*.json: not a relit/NeRF dataset folder");
  return d;
}

}  // namespace relit
