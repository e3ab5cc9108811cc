// Exporting a learned medium: its property network sampled at voxel centres, written as OpenVDB grids.
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/method/export.hpp>
#include <relit/method/medium.hpp>

#if RELIT_WITH_OPENVDB
#include <openvdb/openvdb.h>
#endif

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <sstream>

namespace fs = std::filesystem;

namespace relit::method {

namespace {

const MediumModel& medium_model(const Model& model) {
  const auto* m = dynamic_cast<const MediumModel*>(&model);
  if (!m || m->parts().scattering.is_brdf())
    throw InvalidArgument("method '" + model.method() +
                          "' learns no participating medium (no albedo and phase function) to export");
  return *m;
}

// The folder `path` goes into must exist (the writers would fail with less helpful messages).
void check_parent(const std::string& path, const std::string& what) {
  if (path.empty()) throw IOError(what + ": no output path given");
  const fs::path parent = fs::absolute(path).parent_path();
  if (!fs::is_directory(parent))
    throw IOError("cannot write " + what + " '" + path + "': the folder '" + parent.string() + "' does not exist");
  if (fs::is_directory(path)) throw IOError("cannot write " + what + " '" + path + "': it is a folder");
}

// σ-weighted mean of g over the voxels with σ above `threshold`.
float weighted_g(const MediumSamples& s, float threshold) {
  double w = 0.0, sum = 0.0;
  for (std::size_t v = 0; v < s.sigma.size(); ++v)
    if (s.sigma[v] > threshold) w += s.sigma[v], sum += double(s.sigma[v]) * s.g[v];
  return w > 0 ? float(sum / w) : 0.0f;
}

// Mitsuba 3's binary grid: "VOL", version 3, encoding 1 (float32), x/y/z resolution, channels, a bounding box
// (the volume's to_world places it instead), then the values, x fastest and the channels innermost.
std::string vol_bytes(const std::vector<float>& values, int n, int channels) {
  std::string out = "VOL";
  out += char(3);
  const std::int32_t header[5] = {1, n, n, n, channels};
  const float box[6] = {-1, -1, -1, 1, 1, 1};
  out.append(reinterpret_cast<const char*>(header), sizeof header);
  out.append(reinterpret_cast<const char*>(box), sizeof box);
  out.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(float));
  return out;
}

std::string num(double v) {
  std::ostringstream s;
  s.precision(9);
  s << v;
  return s.str();
}

std::string scene_xml(const MitsubaExportSettings& st, const std::string& run, const std::string& method, float g) {
  // relit's camera looks down its -z with +x right; Mitsuba's sensor looks down +z with +x left.
  const Matrix4& m = st.camera.transform;
  std::string matrix;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) matrix += (matrix.empty() ? "" : " ") + num(c == 0 || c == 2 ? -m[r][c] : m[r][c]);
  const double fov = st.camera.camera_angle_x * 180.0 / 3.14159265358979323846;
  const auto& l = st.light;
  std::ostringstream x;
  x << "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n"
    << "<!-- The medium relit learned" << (run.empty() ? "" : " in run '" + run + "'") << " (method " << method
    << "), exported by relit export --mitsuba: render with `mitsuba -m scalar_rgb scene.xml` (or any other variant). "
       "-->\n"
    << "<scene version=\"3.0.0\">\n"
    << "  <integrator type=\"volpath\">\n    <integer name=\"max_depth\" value=\"-1\"/>\n  </integrator>\n"
    << "  <sensor type=\"perspective\">\n"
    << "    <string name=\"fov_axis\" value=\"x\"/>\n"
    << "    <float name=\"fov\" value=\"" << num(fov) << "\"/>\n"
    << "    <transform name=\"to_world\">\n      <matrix value=\"" << matrix << "\"/>\n    </transform>\n"
    << "    <sampler type=\"independent\">\n      <integer name=\"sample_count\" value=\"" << st.spp
    << "\"/>\n    </sampler>\n"
    << "    <film type=\"hdrfilm\">\n"
    << "      <integer name=\"width\" value=\"" << st.camera.width << "\"/>\n"
    << "      <integer name=\"height\" value=\"" << st.camera.height << "\"/>\n"
    << "      <string name=\"pixel_format\" value=\"rgb\"/>\n"
    << "      <rfilter type=\"box\"/>\n    </film>\n  </sensor>\n"
    << "  <emitter type=\"point\">\n"
    << "    <point name=\"position\" x=\"" << num(l.position[0]) << "\" y=\"" << num(l.position[1]) << "\" z=\""
    << num(l.position[2]) << "\"/>\n"
    << "    <rgb name=\"intensity\" value=\"" << num(l.intensity[0]) << ", " << num(l.intensity[1]) << ", "
    << num(l.intensity[2]) << "\"/>\n  </emitter>\n"
    << "  <!-- The box [-1, 1]^3 (Mitsuba's cube); the null BSDF makes its surface an index-matched boundary. -->\n"
    << "  <shape type=\"cube\">\n    <bsdf type=\"null\"/>\n"
    << "    <medium name=\"interior\" type=\"heterogeneous\">\n";
  for (const char* grid : {"sigma_t", "albedo"})
    x << "      <volume name=\"" << grid << "\" type=\"gridvolume\">\n"
      << "        <string name=\"filename\" value=\"" << (std::strcmp(grid, "sigma_t") == 0 ? "density" : "albedo")
      << ".vol\"/>\n"
      << "        <transform name=\"to_world\">\n          <scale value=\"2\"/>\n"
      << "          <translate value=\"-1, -1, -1\"/>\n        </transform>\n      </volume>\n";
  x << "      <float name=\"scale\" value=\"1\"/>\n"
    << "      <!-- relit's g varies per voxel; Mitsuba's hg takes one: the extinction-weighted mean. -->\n"
    << "      <phase type=\"hg\">\n        <float name=\"g\" value=\"" << num(g) << "\"/>\n      </phase>\n"
    << "    </medium>\n  </shape>\n</scene>\n";
  return x.str();
}

}  // namespace

MediumSamples sample_medium(const Model& model, int resolution) {
  const MediumModel& m = medium_model(model);
  if (resolution < 8 || resolution > 512)
    throw InvalidArgument("export resolution must lie in [8, 512], got " + std::to_string(resolution));
  const Device& device = m.device();
  const std::uint32_t n_heads = m.parts().scattering.n_heads(), cols = n_heads + m.settings().n_features;
  const float g_scale = m.parts().scattering.g_scale;
  const std::uint64_t total = std::uint64_t(resolution) * resolution * resolution;
  const std::uint32_t chunk = static_cast<std::uint32_t>(std::min<std::uint64_t>(total, 1u << 16));
  nn::BatchMatrix positions(device, chunk, 3), props(device, chunk, cols);
  auto ws = m.property_network().make_workspace(device);
  MediumSamples out;
  out.resolution = resolution;
  out.sigma.resize(total);
  out.albedo.resize(total * 3);
  out.g.resize(total);
  std::vector<float> host;
  for (std::uint64_t first = 0; first < total; first += chunk) {
    const auto n = static_cast<std::uint32_t>(std::min<std::uint64_t>(chunk, total - first));
    positions.resize(n);
    props.resize(n);
    host.resize(std::size_t(n) * 3);
    for (std::uint32_t s = 0; s < n; ++s) {  // the networks see the box as [0, 1]^3
      const std::uint64_t v = first + s;
      const std::uint64_t idx[3] = {v % resolution, (v / resolution) % resolution,
                                    v / (std::uint64_t(resolution) * resolution)};
      for (int c = 0; c < 3; ++c) host[s * 3 + c] = (float(idx[c]) + 0.5f) / float(resolution);
    }
    positions.upload_row_major(host);
    m.property_network().inference(device, {&m.params(), 0}, positions, props, *ws);
    const std::vector<float> p = props.download_row_major();
    for (std::uint32_t s = 0; s < n; ++s) {
      const float* row = &p[std::size_t(s) * cols];
      const std::uint64_t v = first + s;
      out.sigma[v] = row[0];
      for (int c = 0; c < 3; ++c) out.albedo[v * 3 + c] = row[1 + c];
      out.g[v] = g_scale * row[4];
    }
  }
  for (const float s : out.sigma)
    if (!std::isfinite(s)) throw InvalidArgument("the model's density is not finite (a damaged checkpoint?)");
  return out;
}

VdbExportStats export_vdb(const Model& model, const std::string& path, const VdbExportSettings& settings) {
  if (!(settings.threshold >= 0.0f && std::isfinite(settings.threshold)))
    throw InvalidArgument("export threshold must be a finite number >= 0");
  medium_model(model);
  check_parent(path, "OpenVDB file");
#if !RELIT_WITH_OPENVDB
  throw IOError("cannot write OpenVDB file '" + path +
                "': this relit was built without OpenVDB (RELIT_WITH_OPENVDB=OFF)");
#else
  const MediumSamples samples = sample_medium(model, settings.resolution);
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });

  const int n = samples.resolution;
  const double voxel = 2.0 / n;
  auto transform = openvdb::math::Transform::createLinearTransform(voxel);
  transform->postTranslate(openvdb::Vec3d(-1.0 + 0.5 * voxel));  // voxel (0, 0, 0)'s centre
  auto density = openvdb::FloatGrid::create(0.0f);
  auto albedo = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.0f));
  auto g = openvdb::FloatGrid::create(0.0f);
  density->setName("density");
  density->setGridClass(openvdb::GRID_FOG_VOLUME);
  albedo->setName("albedo");
  g->setName("g");
  for (openvdb::GridBase* grid :
       {static_cast<openvdb::GridBase*>(density.get()), static_cast<openvdb::GridBase*>(albedo.get()),
        static_cast<openvdb::GridBase*>(g.get())})
    grid->setTransform(transform->copy());
  auto da = density->getAccessor();
  auto aa = albedo->getAccessor();
  auto ga = g->getAccessor();
  VdbExportStats stats;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const std::size_t v = (std::size_t(k) * n + j) * n + i;
        const float s = samples.sigma[v];
        if (!(s > settings.threshold)) continue;
        const openvdb::Coord c(i, j, k);
        da.setValue(c, s);
        aa.setValue(c, openvdb::Vec3s(samples.albedo[v * 3], samples.albedo[v * 3 + 1], samples.albedo[v * 3 + 2]));
        ga.setValue(c, samples.g[v]);
        ++stats.active_voxels;
        stats.max_sigma = std::max(stats.max_sigma, s);
      }
  stats.mean_g = weighted_g(samples, settings.threshold);

  openvdb::MetaMap meta;
  meta.insertMeta("relit_run", openvdb::StringMetadata(settings.run));
  meta.insertMeta("relit_method", openvdb::StringMetadata(model.method()));
  meta.insertMeta("relit_resolution", openvdb::Int32Metadata(n));
  meta.insertMeta("relit_threshold", openvdb::FloatMetadata(settings.threshold));
  meta.insertMeta("relit_mean_g", openvdb::FloatMetadata(stats.mean_g));
  meta.insertMeta("relit_units", openvdb::StringMetadata("density: extinction per scene unit; box [-1, 1]^3, z up"));
  for (const auto& [key, value] :
       {std::pair<std::string, std::string>{"relit_run", settings.run}, {"relit_method", model.method()}})
    density->insertMeta(key, openvdb::StringMetadata(value));

  openvdb::GridPtrVec grids{density, albedo, g};
  const std::string tmp = io::temporary_sibling(path);
  try {
    openvdb::io::File file(tmp);
    file.write(grids, meta);
    file.close();
  } catch (const openvdb::Exception& e) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw IOError("cannot write OpenVDB file '" + path + "': " + e.what());
  }
  io::replace_file(tmp, path);
  return stats;
#endif
}

MitsubaExportStats export_mitsuba(const Model& model, const std::string& dir, const MitsubaExportSettings& settings) {
  medium_model(model);
  settings.camera.validate();
  settings.light.validate();
  if (settings.spp < 1) throw InvalidArgument("Mitsuba export: spp must be at least 1");
  if (dir.empty()) throw IOError("Mitsuba export: no output folder given");
  const fs::path target = fs::absolute(dir).lexically_normal();
  const fs::path folder = target.filename().empty() ? target.parent_path() : target;
  if (fs::exists(folder))
    throw IOError("cannot write the Mitsuba scene to '" + dir + "': it exists (choose a new folder or remove it)");
  if (!fs::is_directory(folder.parent_path()))
    throw IOError("cannot write the Mitsuba scene to '" + dir + "': the folder '" + folder.parent_path().string() +
                  "' does not exist");
  const MediumSamples samples = sample_medium(model, settings.resolution);
  MitsubaExportStats stats;
  stats.mean_g = weighted_g(samples, 0.0f);
  for (const float s : samples.sigma) stats.max_sigma = std::max(stats.max_sigma, s);
  const fs::path tmp =
      folder.parent_path() / ("." + folder.filename().string() + ".partial-" + std::to_string(::getpid()));
  std::error_code ec;
  fs::remove_all(tmp, ec);
  try {
    io::create_directories(tmp.string(), "the Mitsuba scene's temporary folder");
    io::write_file_atomic((tmp / "density.vol").string(), vol_bytes(samples.sigma, samples.resolution, 1));
    io::write_file_atomic((tmp / "albedo.vol").string(), vol_bytes(samples.albedo, samples.resolution, 3));
    io::write_file_atomic((tmp / "scene.xml").string(),
                          scene_xml(settings, settings.run, model.method(), stats.mean_g));
    io::rename_directory(tmp.string(), folder.string());
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  return stats;
}

}  // namespace relit::method
