// Scene JSON: parsing (every key checked, every default recorded), built-in scenes, file loading.
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/scene/procedural.hpp>
#include <relit/scene/scene.hpp>
#include <relit/scene/vdb.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;

namespace relit {

namespace {

using config::Reader;

Float3 read_vec3(Reader& r, const std::string& key, const Float3& def, float lo, float hi, const std::string& doc) {
  const Json j = r.sub(key, Json(def), "array", doc + " (3 numbers, or one number for all three)");
  Float3 v{};
  if (j.is_number()) {
    v.fill(j.get<float>());
  } else if (j.is_array() && j.size() == 3 && j[0].is_number() && j[1].is_number() && j[2].is_number()) {
    for (int c = 0; c < 3; ++c) v[c] = j[c].get<float>();
  } else {
    r.fail(key, "must be an array of 3 numbers (or one number), got " + j.dump());
  }
  for (float x : v)
    if (!std::isfinite(x) || x < lo || x > hi)
      r.fail(key, "values must lie in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + j.dump());
  r.set_resolved(key, Json(v));
  return v;
}

Matrix4 read_matrix(Reader& r, const std::string& key) {
  const Json j = r.sub(key, Json(), "array", "camera-to-world 4x4 matrix (rows), OpenGL/Blender axes");
  Matrix4 m{};
  bool ok = j.is_array() && j.size() == 4;
  for (int i = 0; ok && i < 4; ++i) {
    ok = j[i].is_array() && j[i].size() == 4;
    for (int k = 0; ok && k < 4; ++k) {
      ok = j[i][k].is_number() && std::isfinite(j[i][k].get<double>());
      if (ok) m[i][k] = j[i][k].get<float>();
    }
  }
  if (!ok) r.fail(key, "must be a 4x4 array of finite numbers (a list of 4 rows), got " + j.dump());
  return m;
}

Reader reader_for(const Json& j, const std::string& pointer, const std::string& component) {
  if (!j.is_object()) throw ConfigError(pointer, component + " must be a JSON object, got " + j.dump());
  return Reader(j, pointer, component);
}

std::string resolve_path(const std::string& file, const std::string& base_dir) {
  fs::path p(file);
  return p.is_absolute() ? p.string() : (fs::path(base_dir) / p).lexically_normal().string();
}

// {"type": ..., params}: the density (and possibly albedo) grid of a medium.
ProceduralMedium read_medium_source(const Json& j, const std::string& ptr, const std::string& base_dir,
                                    Json& resolved) {
  if (!j.is_object()) throw ConfigError(ptr, "the medium source must be an object with a \"type\"");
  const std::string type = config::component_type(j, ptr, "cloud");
  Json body = j;
  body.erase("type");
  body.erase("otype");
  Reader r(body, ptr, "medium source '" + type + "'");
  ProceduralMedium m;
  if (type == "cloud" || type == "smoke" || type == "blobs") {
    const int res = int(r.uint("resolution", 64, 8, 512, "grid voxels per side"));
    const unsigned seed = r.uint("seed", 0, 0, 0xFFFFFFFFu, "random seed of the generator");
    m = type == "cloud" ? make_cloud(res, seed) : type == "smoke" ? make_smoke(res, seed) : make_blobs(res, seed);
  } else if (type == "constant") {
    const int res = int(r.uint("resolution", 8, 2, 512, "grid voxels per side"));
    const float v = r.number("value", 1.0f, 0.0f, 1e6f, "density everywhere in the box");
    m.density = Grid(res, res, res, 1, v);
  } else if (type == "sphere") {
    const int res = int(r.uint("resolution", 64, 8, 512, "grid voxels per side"));
    const float radius = r.number("radius", 0.8f, 0.05f, 1.0f, "sphere radius");
    const float v = r.number("value", 1.0f, 0.0f, 1e6f, "density inside the sphere");
    m.density = Grid(res, res, res, 1);
    for (int k = 0; k < res; ++k)
      for (int jj = 0; jj < res; ++jj)
        for (int i = 0; i < res; ++i) {
          const Float3 p = m.density.centre(i, jj, k);
          m.density.at(i, jj, k) = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) <= radius ? v : 0.0f;
        }
  } else if (type == "vdb") {
    const std::string file = r.string("file", "", "path of the .vdb file (relative to the scene file)");
    if (file.empty()) r.fail("file", "a vdb source needs \"file\": the path of a .vdb fog volume");
    const std::string grid = r.string("grid", "", "name of the float grid ('' = 'density' or the first float grid)");
    const int res = int(r.uint("resolution", 64, 8, 512, "dense grid voxels per side"));
    const std::string placement =
        r.choice("placement", "fit", {"fit", "world"},
                 "fit: the volume is centred and scaled into the box and normalised to [0, 1]; world: it stays where "
                 "its transform puts it and its values are kept (extinction per scene unit, as relit export writes; "
                 "a vec3 grid 'albedo' becomes the albedo grid)");
    if (placement == "world") {
      if (r.has("fill")) r.fail("fill", "\"fill\" is for placement \"fit\"; a \"world\" volume keeps its size");
      const std::string path = resolve_path(file, base_dir);
      m.density = load_vdb_world(path, grid, res);
      if (read_vdb_info(path).has("albedo")) m.albedo = load_vdb_world(path, "albedo", res);
    } else {
      const float fill = r.number("fill", 0.9f, 0.1f, 1.0f, "fraction of the box the longest side of the volume spans");
      m.density = load_vdb_density(resolve_path(file, base_dir), grid, res, fill);
    }
    // The resolved description must load from anywhere (it is copied next to datasets): absolute path.
    r.set_resolved("file", fs::absolute(resolve_path(file, base_dir)).lexically_normal().string());
  } else {
    throw ConfigError(ptr + "/type", "unknown medium source type '" + type +
                                         "'; valid types: cloud, smoke, blobs, constant, sphere, vdb");
  }
  r.finish();
  resolved = Json{{"type", type}};
  resolved.update(r.resolved());
  return m;
}

Grid read_solid_source(const Json& j, const std::string& ptr, Json& resolved) {
  if (!j.is_object()) throw ConfigError(ptr, "the solid source must be an object with a \"type\"");
  const std::string type = config::component_type(j, ptr, "spheres");
  Json body = j;
  body.erase("type");
  body.erase("otype");
  Reader r(body, ptr, "solid source '" + type + "'");
  Grid g;
  const int res = int(r.uint("resolution", 64, 8, 512, "SDF grid voxels per side"));
  if (type == "spheres" || type == "torus") {
    const unsigned seed = r.uint("seed", 0, 0, 0xFFFFFFFFu, "random seed of the generator");
    g = type == "spheres" ? make_spheres_sdf(res, seed) : make_torus_sdf(res, seed);
  } else if (type == "sphere") {
    const float radius = r.number("radius", 0.6f, 0.05f, 0.95f, "sphere radius");
    g = Grid(res, res, res, 1);
    for (int k = 0; k < res; ++k)
      for (int jj = 0; jj < res; ++jj)
        for (int i = 0; i < res; ++i) {
          const Float3 p = g.centre(i, jj, k);
          g.at(i, jj, k) = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) - radius;
        }
  } else {
    throw ConfigError(ptr + "/type", "unknown solid source type '" + type + "'; valid types: spheres, torus, sphere");
  }
  r.finish();
  resolved = Json{{"type", type}};
  resolved.update(r.resolved());
  return g;
}

template <class F>
auto rethrow_as_config(const std::string& ptr, F f) {
  try {
    return f();
  } catch (const ConfigError&) {
    throw;
  } catch (const InvalidArgument& e) {
    throw ConfigError(ptr, e.what());
  }
}

}  // namespace

Scene Scene::from_json(const Json& json, const std::string& base_dir) {
  Reader root = reader_for(json, "", "scene");
  Scene s;

  const Json jm = root.sub("medium", Json(), "object", "participating medium");
  if (!jm.is_null()) {
    Reader r = reader_for(jm, "/medium", "medium");
    Json src_resolved;
    ProceduralMedium src =
        read_medium_source(r.sub("source", Json{{"type", "cloud"}}, "object", "where the density comes from"),
                           "/medium/source", base_dir, src_resolved);
    r.set_resolved("source", src_resolved);
    Medium m;
    m.density = std::move(src.density);
    m.density_scale = r.number("density_scale", 20.0f, 0.0f, 1e5f, "extinction per unit density (1/scene unit)");
    const bool has_grid_albedo = !src.albedo.empty();
    const bool grid_requested = jm.contains("albedo") && jm["albedo"] == "grid";
    if (grid_requested && !has_grid_albedo)
      r.fail("albedo", "\"grid\" needs a source with an albedo grid (blobs); give [r, g, b] instead");
    if (grid_requested)
      r.sub("albedo", "grid", "array", "single-scattering albedo (RGB), or \"grid\" for the source's");
    if (!grid_requested && (r.has("albedo") || !has_grid_albedo)) {
      m.albedo = read_vec3(r, "albedo", {0.95f, 0.95f, 0.95f}, 0.0f, 1.0f, "single-scattering albedo (RGB)");
    } else {
      m.albedo_grid = std::move(src.albedo);
      r.set_resolved("albedo", "grid");
    }
    m.g = r.number("g", 0.0f, -1.0f, 1.0f, "Henyey-Greenstein asymmetry in (-1, 1)");
    if (!(m.g > -1.0f && m.g < 1.0f)) r.fail("g", "must lie strictly inside (-1, 1), got " + std::to_string(m.g));
    r.finish();
    rethrow_as_config("/medium", [&] {
      m.validate();
      return 0;
    });
    s.medium = std::move(m);
    root.set_resolved("medium", r.resolved());
  }

  const Json js = root.sub("solid", Json(), "object", "solid object (SDF + GGX material)");
  if (!js.is_null()) {
    Reader r = reader_for(js, "/solid", "solid");
    Json src_resolved;
    Surface surf;
    surf.sdf = read_solid_source(r.sub("source", Json{{"type", "spheres"}}, "object", "where the SDF comes from"),
                                 "/solid/source", src_resolved);
    r.set_resolved("source", src_resolved);
    surf.base_color = read_vec3(r, "base_color", {0.8f, 0.8f, 0.8f}, 0.0f, 1.0f, "diffuse albedo (RGB)");
    surf.roughness = r.number("roughness", 0.4f, 0.02f, 1.0f, "GGX roughness r (alpha = r^2)");
    r.finish();
    rethrow_as_config("/solid", [&] {
      surf.validate();
      return 0;
    });
    s.solid = std::move(surf);
    root.set_resolved("solid", r.resolved());
  }

  const Json jl = root.sub("lights", Json::array(), "array", "point lights");
  if (!jl.is_array()) root.fail("lights", "must be an array of light objects");
  Json lights_resolved = Json::array();
  for (std::size_t i = 0; i < jl.size(); ++i) {
    const std::string ptr = "/lights/" + std::to_string(i);
    Reader r = reader_for(jl[i], ptr, "light");
    r.choice("type", "point", {"point"}, "light type");
    PointLight l;
    l.position = read_vec3(r, "position", {0, 0, 4}, -1e6f, 1e6f, "position (scene units)");
    l.intensity = read_vec3(r, "intensity", {600, 600, 600}, 0.0f, 1e9f, "radiant intensity, W/sr per channel, >= 0");
    r.finish();
    try {
      l.validate();
    } catch (const InvalidArgument& e) {
      throw ConfigError(ptr + "/position", e.what());
    }
    s.lights.push_back(l);
    lights_resolved.push_back(r.resolved());
  }
  root.set_resolved("lights", lights_resolved);

  const Json je = root.sub("environment", Json(), "object", "environment light");
  if (!je.is_null()) {
    Reader r = reader_for(je, "/environment", "environment");
    const float scale = r.number("scale", 1.0f, 0.0f, 1e6f, "radiance multiplier");
    const bool visible = r.boolean("visible", false, "whether camera rays that miss everything see it");
    const int count = int(r.has("file")) + int(r.has("radiance")) + int(r.has("sky"));
    if (count != 1)
      throw ConfigError(
          "/environment",
          "give exactly one of \"file\" (lat-long HDR image), \"radiance\" ([r, g, b]) or \"sky\" (seed)");
    if (r.has("file")) {
      const std::string file = r.string("file", "", "lat-long HDR image (EXR/HDR), relative to the scene file");
      Image img = read_image(resolve_path(file, base_dir));
      s.environment =
          rethrow_as_config("/environment", [&] { return EnvironmentLight(std::move(img), scale, visible, file); });
    } else if (r.has("radiance")) {
      const Float3 rad = read_vec3(r, "radiance", {1, 1, 1}, 0.0f, 1e6f, "uniform radiance (RGB)");
      Float3 scaled{rad[0] * scale, rad[1] * scale, rad[2] * scale};
      s.environment = rethrow_as_config("/environment", [&] { return EnvironmentLight::uniform(scaled, visible); });
    } else {
      const unsigned seed = r.uint("sky", 0, 0, 0xFFFFFFFFu, "seed of a procedural sky (sun position)");
      s.environment = EnvironmentLight::sky(256, 128, seed, scale, visible);
    }
    r.finish();
    root.set_resolved("environment", r.resolved());
  }

  const Json jc = root.sub("cameras", Json::array(), "array", "cameras");
  if (!jc.is_array()) root.fail("cameras", "must be an array of camera objects");
  Json cams_resolved = Json::array();
  for (std::size_t i = 0; i < jc.size(); ++i) {
    const std::string ptr = "/cameras/" + std::to_string(i);
    Reader r = reader_for(jc[i], ptr, "camera");
    const float angle = r.number("camera_angle_x", 0.8f, 0.02f, 3.0f, "horizontal field of view (radians)");
    const int w = int(r.uint("width", 128, 1, 16384, "pixels")), h = int(r.uint("height", 128, 1, 16384, "pixels"));
    Camera c;
    if (r.has("transform_matrix")) {
      c.transform = read_matrix(r, "transform_matrix");
      c.camera_angle_x = angle, c.width = w, c.height = h;
    } else {
      const Float3 pos = read_vec3(r, "position", {0, -4.5f, 0}, -1e6f, 1e6f, "eye position");
      const Float3 target = read_vec3(r, "target", {0, 0, 0}, -1e6f, 1e6f, "point looked at");
      const Float3 up = read_vec3(r, "up", {0, 0, 1}, -1.0f, 1.0f, "up direction");
      c = Camera::look_at(pos, target, up, angle, w, h);
    }
    r.finish();
    rethrow_as_config(ptr, [&] {
      c.validate();
      return 0;
    });
    s.cameras.push_back(c);
    cams_resolved.push_back(r.resolved());
  }
  root.set_resolved("cameras", cams_resolved);
  root.finish();
  if (!s.medium && !s.solid) throw ConfigError("", "a scene needs a \"medium\" or a \"solid\" (or both)");
  s.description = root.resolved();
  return s;
}

Scene Scene::load(const std::string& path) {
  if (!fs::is_regular_file(path)) throw IOError("cannot open scene file '" + path + "': no such file");
  if (const std::string ext = fs::path(path).extension().string(); ext == ".vdb" || ext == ".VDB")
    return from_json(vdb_json(path));
  const Json j = parse_json(io::read_file(path), "scene file '" + path + "'");
  try {
    return from_json(j, fs::path(path).parent_path().string().empty() ? "." : fs::path(path).parent_path().string());
  } catch (const ConfigError& e) {
    throw ConfigError(e.pointer(), e.message() + " (in '" + path + "')");
  }
}

const std::vector<std::string>& Scene::builtin_names() {
  static const std::vector<std::string> names = {"cloud", "smoke", "blobs", "spheres", "torus"};
  return names;
}

Json Scene::builtin_json(const std::string& name, unsigned seed, int resolution) {
  if (name == "cloud")
    return {{"medium",
             {{"source", {{"type", "cloud"}, {"resolution", resolution}, {"seed", seed}}},
              {"density_scale", 20.0},
              {"albedo", {0.96, 0.96, 0.96}},
              {"g", 0.4}}}};
  if (name == "smoke")
    return {{"medium",
             {{"source", {{"type", "smoke"}, {"resolution", resolution}, {"seed", seed}}},
              {"density_scale", 30.0},
              {"albedo", {0.85, 0.85, 0.85}},
              {"g", 0.2}}}};
  if (name == "blobs")
    return {{"medium",
             {{"source", {{"type", "blobs"}, {"resolution", resolution}, {"seed", seed}}},
              {"density_scale", 15.0},
              {"g", 0.0}}}};
  if (name == "spheres")
    return {{"solid",
             {{"source", {{"type", "spheres"}, {"resolution", resolution}, {"seed", seed}}},
              {"base_color", {0.75, 0.45, 0.3}},
              {"roughness", 0.35}}}};
  if (name == "torus")
    return {{"solid",
             {{"source", {{"type", "torus"}, {"resolution", resolution}, {"seed", seed}}},
              {"base_color", {0.3, 0.5, 0.8}},
              {"roughness", 0.25}}}};
  std::string valid;
  for (const auto& n : builtin_names()) valid += (valid.empty() ? "" : ", ") + n;
  throw InvalidArgument("unknown built-in scene '" + name + "'; valid names: " + valid +
                        ", or a path to a scene .json file");
}

Json Scene::vdb_json(const std::string& path) {
  const VdbInfo info = read_vdb_info(path);
  const std::string file = fs::absolute(path).lexically_normal().string();
  // Any other fog volume: fitted into the box and normalised, with the medium's default scale and albedo.
  if (!info.metadata.count("relit_units")) return {{"medium", {{"source", {{"type", "vdb"}, {"file", file}}}}}};
  const int res = info.resolution >= 8 && info.resolution <= 512 ? info.resolution : 64;
  Json medium = {{"source", {{"type", "vdb"}, {"file", file}, {"placement", "world"}, {"resolution", res}}},
                 {"density_scale", 1.0}};
  if (info.has("albedo")) medium["albedo"] = "grid";
  if (const auto it = info.metadata.find("relit_mean_g"); it != info.metadata.end()) {
    try {
      const float g = std::stof(it->second);
      if (g > -1.0f && g < 1.0f) medium["g"] = g;
    } catch (const std::exception&) {}
  }
  return {{"medium", medium}};
}

Scene Scene::builtin_or_file(const std::string& name_or_path, unsigned seed, int resolution) {
  const std::string ext = fs::path(name_or_path).extension().string();
  if (ext == ".json" || ext == ".JSON") return load(name_or_path);
  if (ext == ".vdb" || ext == ".VDB") return load(name_or_path);
  return from_json(builtin_json(name_or_path, seed, resolution));
}

}  // namespace relit
