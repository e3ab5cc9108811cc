// Dataset generation: view planning, rendering through the reference path tracer, atomic folder writes.
#include <relit/dataset.hpp>
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/io/image.hpp>
#include <relit/log.hpp>
#include <relit/version.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <unistd.h>

namespace fs = std::filesystem;

namespace relit {

namespace {

constexpr double kPi = 3.14159265358979323846;

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

Float3 vec_from(const Json& j, const std::string& what) {
  if (!j.is_array() || j.size() != 3) throw IOError("dataset: " + what + " must be an array of 3 numbers");
  return {j[0].get<float>(), j[1].get<float>(), j[2].get<float>()};
}

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
  // Generalisation studies (seed, appendix H): the same cameras and light directions, one varying factor.
  if (s.generalization) {
    auto rng = stream(s.seed, 4);
    std::vector<std::pair<Float3, Float3>> views;
    for (std::uint32_t i = 0; i < s.generalization_views; ++i)
      views.push_back({unit_from(u(rng), u(rng)), unit_from(u(rng), u(rng))});
    for (int dist : {3, 5, 7, 10}) {
      const std::string name = "test_distance_" + std::to_string(dist);
      for (std::size_t i = 0; i < views.size(); ++i)
        d.splits[name].push_back(
            {frame_name(name, i) + ".exr", camera_at(views[i].first, s), light_of(views[i].second, dist, 600.0f)});
    }
    for (int inten : {400, 800, 1200, 1600}) {
      const std::string name = "test_intensity_" + std::to_string(inten);
      for (std::size_t i = 0; i < views.size(); ++i)
        d.splits[name].push_back(
            {frame_name(name, i) + ".exr", camera_at(views[i].first, s), light_of(views[i].second, 4.0, float(inten))});
    }
  }
  return d;
}

void generate_dataset(const Device& device, const Scene& input_scene, const std::string& out_dir,
                      const DatasetSettings& s, const ProgressCallback& progress) {
  s.validate();
  const fs::path out = fs::path(out_dir).lexically_normal();
  if (out.empty()) throw InvalidArgument("the output folder is empty");
  if (fs::exists(out) && !s.overwrite)
    throw IOError("output folder '" + out.string() +
                  "' already exists; choose another --out or pass --overwrite "
                  "(the existing folder is left untouched)");
  const fs::path parent = out.has_parent_path() ? out.parent_path() : fs::path(".");
  if (!fs::is_directory(parent)) throw IOError("the parent folder of '" + out.string() + "' does not exist");

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
  std::uint64_t total = 0;
  for (const auto& [name, frames] : plan.splits)
    total += frames.size() * std::uint64_t(s.resolution) * s.resolution * split_spp(name);
  ProgressTracker tracker(progress, total, "samples");

  const fs::path tmp = parent / ("." + out.filename().string() + ".partial-" + std::to_string(::getpid()));
  fs::remove_all(tmp);
  fs::create_directories(tmp);
  try {
    if (scene.environment) {
      write_image((tmp / "environment.exr").string(), scene.environment->image());
      env_json = {{"file", "environment.exr"},
                  {"scale", scene.environment->scale()},
                  {"visible", scene.environment->visible()}};
      scene_json["environment"] = env_json;
    }
    io::write_file_atomic((tmp / "scene.json").string(), scene_json.dump(2) + "\n");

    const PathTracer pt(device, scene);
    PathTraceSettings rs;
    rs.spp = s.spp;
    rs.max_bounces = s.max_bounces;
    std::uint64_t samples_done = 0;
    for (const auto& [name, frames] : plan.splits) {
      if (frames.empty()) continue;
      rs.spp = split_spp(name);
      const std::uint64_t view_samples = std::uint64_t(s.resolution) * s.resolution * rs.spp;
      fs::create_directories(tmp / name);
      Json doc = {{"camera_angle_x", s.camera_angle_x},
                  {"w", s.resolution},
                  {"h", s.resolution},
                  {"lighting", s.lighting},
                  {"environment", env_json},
                  {"scene", "scene.json"},
                  {"spp", rs.spp},
                  {"seed", s.seed},
                  {"relit_version", relit::version()},
                  {"frames", Json::array()}};
      for (std::size_t i = 0; i < frames.size(); ++i) {
        const DatasetFrame& f = frames[i];
        rs.seed = dataset_view_seed(s.seed, name, i);
        const std::string stem = f.file_path.substr(0, f.file_path.size() - 4);
        const std::uint64_t base = samples_done;
        ProgressCallback per_view;  // without a callback, launches run back to back with no waiting
        if (progress)
          per_view = [&](const Progress& p) {
            tracker.update(base + p.done, stem);
            return true;
          };
        const RenderResult r = pt.render(f.camera, {f.light}, rs, per_view);
        write_image((tmp / f.file_path).string(), r.image);
        if (s.previews) {
          Image rgb(r.image.width, r.image.height, 3);
          for (std::size_t p = 0; p < std::size_t(r.image.width) * r.image.height; ++p)
            for (int c = 0; c < 3; ++c) {
              const float v = std::max(r.image.pixels[p * 4 + c], 0.0f);
              rgb.pixels[p * 3 + c] = v / (1.0f + v);  // Reinhard: highlights stay readable in 8 bits
            }
          write_image((tmp / (stem + ".png")).string(), rgb);
        }
        Json m = Json::array();
        for (const auto& row : f.camera.transform) m.push_back(Json::array({row[0], row[1], row[2], row[3]}));
        Json frame = {{"file_path", f.file_path},
                      {"transform_matrix", m},
                      {"light",
                       {{"type", "point"},
                        {"position", vec_json(f.light.position)},
                        {"intensity", vec_json(f.light.intensity)}}}};
        if (s.previews) frame["preview_path"] = stem + ".png";
        doc["frames"].push_back(frame);
        samples_done += view_samples;
      }
      io::write_file_atomic((tmp / ("transforms_" + name + ".json")).string(), doc.dump(2) + "\n");
    }
    // Complete: move it into place. An existing folder is replaced only now, and only on request.
    if (fs::exists(out)) {
      const fs::path old = parent / ("." + out.filename().string() + ".old-" + std::to_string(::getpid()));
      fs::remove_all(old);
      fs::rename(out, old);
      fs::rename(tmp, out);
      fs::remove_all(old);
    } else {
      fs::rename(tmp, out);
    }
  } catch (...) {
    std::error_code ec;
    fs::remove_all(tmp, ec);
    throw;
  }
  log_info("dataset written to " + out.string());
}

DatasetDescription read_dataset(const std::string& dir) {
  if (!fs::is_directory(dir)) throw IOError("dataset folder '" + dir + "' does not exist");
  DatasetDescription d;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const std::string fname = entry.path().filename().string();
    if (fname.rfind("transforms_", 0) != 0 || entry.path().extension() != ".json") continue;
    const std::string split = fname.substr(11, fname.size() - 11 - 5);
    std::ifstream f(entry.path());
    Json doc;
    try {
      doc = Json::parse(f);
      const std::string where = "dataset file '" + entry.path().string() + "'";
      const float angle = doc.at("camera_angle_x").get<float>();
      if (!(angle > 0.0f && angle < 3.14159265f))
        throw IOError(where + ": \"camera_angle_x\" must be a horizontal field of view in (0, pi) radians, got " +
                      doc["camera_angle_x"].dump());
      // The image size, checked before it becomes an int (1e300 would be undefined behaviour).
      const auto size = [&](const char* key) {
        if (!doc.contains(key)) return 0;
        const Json& v = doc[key];
        if (!v.is_number_unsigned() || v.get<std::uint64_t>() < 1 || v.get<std::uint64_t>() > 16384)
          throw IOError(where + ": \"" + key + "\" must be an integer in [1, 16384] (pixels), got " + v.dump());
        return v.get<int>();
      };
      const int w = size("w"), h = size("h");
      d.lighting = doc.value("lighting", "");
      d.environment = doc.value("environment", Json());
      auto& frames = d.splits[split];
      for (const auto& fr : doc.at("frames")) {
        DatasetFrame frame;
        frame.file_path = fr.at("file_path").get<std::string>();
        const Json& m = fr.at("transform_matrix");
        for (int r = 0; r < 4; ++r)
          for (int c = 0; c < 4; ++c) frame.camera.transform[r][c] = m.at(r).at(c).get<float>();
        frame.camera.camera_angle_x = angle;
        frame.camera.width = w;
        frame.camera.height = h;
        if (fr.contains("light")) {
          frame.light.position = vec_from(fr["light"].at("position"), "light position");
          frame.light.intensity = vec_from(fr["light"].at("intensity"), "light intensity");
        }
        frames.push_back(frame);
      }
    } catch (const Json::exception& e) {
      throw IOError("dataset file '" + entry.path().string() + "' is malformed: " + e.what());
    }
  }
  if (d.splits.empty()) throw IOError("'" + dir + "' holds no transforms_*.json: not a relit/NeRF dataset folder");
  return d;
}

}  // namespace relit
