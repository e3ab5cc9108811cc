// Host side of the reference path tracer: scene upload, tiling into short launches, accumulation.
#include <relit/cl/buffer.hpp>
#include <relit/cl/program.hpp>
#include <relit/error.hpp>
#include <relit/pathtrace.hpp>

#include <algorithm>
#include <cmath>

namespace relit {

void PathTraceSettings::validate() const {
  if (spp < 1 || spp > (1u << 24)) throw InvalidArgument("spp must lie in [1, 16777216], got " + std::to_string(spp));
  if (rr_depth < 1) throw InvalidArgument("rr_depth must be >= 1");
  if (samples_per_launch < 1) throw InvalidArgument("samples_per_launch must be >= 1");
}

namespace {

cl_int4 dims(const Grid& g, int flag) { return cl_int4{{g.nx, g.ny, g.nz, flag}}; }

std::vector<cl_float4> to_float4(const std::vector<float>& v, int channels) {
  std::vector<cl_float4> out(v.size() / channels);
  for (std::size_t i = 0; i < out.size(); ++i) {
    cl_float4 f{{0, 0, 0, 1}};
    for (int c = 0; c < channels && c < 4; ++c) f.s[c] = v[i * channels + c];
    out[i] = f;
  }
  return out;
}

}  // namespace

struct PathTracer::Impl {
  Device device;
  Kernel kernel;
  std::size_t local = 0;
  // medium
  Buffer<float> density, majorant;
  cl_int4 density_dims{{1, 1, 1, 0}}, majorant_dims{{1, 1, 1, 0}};
  float density_scale = 0;
  Buffer<cl_float4> albedo;
  cl_int4 albedo_dims{{1, 1, 1, 0}};
  cl_float4 albedo_g{{1, 1, 1, 0}};
  // solid
  Buffer<float> sdf;
  cl_int4 sdf_dims{{1, 1, 1, 0}};
  cl_float4 material{{0.8f, 0.8f, 0.8f, 0.5f}};
  // environment
  Buffer<cl_float4> env;
  Buffer<float> env_pdf, env_marginal, env_conditional;
  cl_int4 env_dims{{1, 1, 0, 0}};
  float env_scale = 1;
};

PathTracer::PathTracer(const Device& device, const Scene& scene) : m_impl(std::make_unique<Impl>()) {
  Impl& m = *m_impl;
  m.device = device;
  m.kernel = device.kernel("pathtrace.cl", "pathtrace_render");
  // CPU drivers gain nothing from large groups; GPUs want a few warps. Both from the device's own numbers.
  const std::size_t multiple = std::max<std::size_t>(1, m.kernel.preferred_work_group_multiple());
  m.local = std::min(m.kernel.max_work_group_size(), multiple * (device.info().type == "gpu" ? 2 : 4));
  if (scene.medium) {
    const Medium& med = *scene.medium;
    med.validate();
    m.density = Buffer<float>(device, med.density.values);
    m.density_dims = dims(med.density, 1);
    m.density_scale = med.density_scale;
    // Majorant cells of about 4 voxels: small enough to bound tightly, big enough to step through quickly.
    const int block = std::max(1, std::max({med.density.nx, med.density.ny, med.density.nz}) / 16);
    const Grid maj = majorant_grid(med.density, med.density_scale, block);
    m.majorant = Buffer<float>(device, maj.values);
    m.majorant_dims = dims(maj, 1);
    if (!med.albedo_grid.empty()) {
      m.albedo = Buffer<cl_float4>(device, to_float4(med.albedo_grid.values, 3));
      m.albedo_dims = dims(med.albedo_grid, 1);
    }
    m.albedo_g = cl_float4{{med.albedo[0], med.albedo[1], med.albedo[2], med.g}};
  }
  if (scene.solid) {
    const Surface& s = *scene.solid;
    s.validate();
    m.sdf = Buffer<float>(device, s.sdf.values);
    m.sdf_dims = dims(s.sdf, 1);
    m.material = cl_float4{{s.base_color[0], s.base_color[1], s.base_color[2], s.roughness}};
  }
  if (scene.environment && !scene.environment->empty()) {
    const EnvironmentLight& e = *scene.environment;
    m.env = Buffer<cl_float4>(device, to_float4(e.image().pixels, e.image().channels));
    m.env_pdf = Buffer<float>(device, e.pdf_uv());
    m.env_marginal = Buffer<float>(device, e.marginal_cdf());
    m.env_conditional = Buffer<float>(device, e.conditional_cdf());
    m.env_dims = cl_int4{{e.image().width, e.image().height, 1, e.visible() ? 1 : 0}};
    m.env_scale = e.scale();
  }
}

PathTracer::~PathTracer() = default;
PathTracer::PathTracer(PathTracer&&) noexcept = default;
PathTracer& PathTracer::operator=(PathTracer&&) noexcept = default;
const Device& PathTracer::device() const { return m_impl->device; }

RenderResult PathTracer::render(const Camera& camera, const std::vector<PointLight>& lights,
                                const PathTraceSettings& rs, const ProgressCallback& progress) const {
  const Impl& m = *m_impl;
  rs.validate();
  camera.validate();
  for (const auto& l : lights) l.validate();
  const std::size_t pixels = std::size_t(camera.width) * camera.height;

  std::vector<cl_float4> light_data;
  for (const auto& l : lights) {
    light_data.push_back(cl_float4{{l.position[0], l.position[1], l.position[2], 0}});
    light_data.push_back(cl_float4{{l.intensity[0], l.intensity[1], l.intensity[2], 0}});
  }
  if (light_data.empty()) light_data.resize(2, cl_float4{{0, 0, 0, 0}});  // never read: n_lights = 0
  Buffer<cl_float4> light_buffer(m.device, light_data);
  Buffer<cl_float4> accum(m.device, pixels), accum_sq(m.device, pixels);
  accum.fill(cl_float4{{0, 0, 0, 0}});
  accum_sq.fill(cl_float4{{0, 0, 0, 0}});

  cl_float4 rows[3];
  for (int r = 0; r < 3; ++r)
    rows[r] =
        cl_float4{{camera.transform[r][0], camera.transform[r][1], camera.transform[r][2], camera.transform[r][3]}};
  const cl_float4 params{{camera.focal(), float(camera.width), float(camera.height), 0}};

  // Passes of `chunk` samples over tiles of `tile` pixels, each launch about samples_per_launch samples.
  const std::uint32_t chunk = std::uint32_t(std::clamp<std::size_t>(rs.samples_per_launch / pixels, 1, rs.spp));
  const std::size_t tile = std::clamp<std::size_t>(rs.samples_per_launch / chunk, 1, pixels);
  ProgressTracker tracker(progress, std::uint64_t(pixels) * rs.spp, "samples");
  std::uint64_t done = 0;
  Kernel k = m.kernel;
  for (std::uint32_t s0 = 0; s0 < rs.spp; s0 += chunk) {
    const cl_uint count = std::min(chunk, rs.spp - s0);
    for (std::size_t p0 = 0; p0 < pixels; p0 += tile) {
      const cl_uint n = cl_uint(std::min(tile, pixels - p0));
      k.args(n, cl_uint(p0), cl_uint(s0), count, cl_uint(rs.seed), cl_uint(camera.width), rows[0], rows[1], rows[2],
             params, cl_uint(rs.max_bounces), cl_uint(rs.rr_depth), m.density, m.density_dims, m.density_scale,
             m.majorant, m.majorant_dims, m.albedo, m.albedo_dims, m.albedo_g, m.sdf, m.sdf_dims, m.material,
             light_buffer, cl_uint(lights.size()), m.env, m.env_pdf, m.env_marginal, m.env_conditional, m.env_dims,
             m.env_scale, accum, accum_sq);
      k.launch(n, m.local);
      if (progress) {
        m.device.finish();  // rendering is not a training step: waiting here lets progress (and cancel) flow
        done += std::uint64_t(n) * count;
        tracker.update(done, "rendering");
      }
    }
  }
  const std::vector<cl_float4> sum = accum.read(), sum_sq = accum_sq.read();
  RenderResult out;
  out.spp = rs.spp;
  out.image = Image(camera.width, camera.height, 4);
  out.variance = Image(camera.width, camera.height, 4);
  const double inv = 1.0 / rs.spp;
  for (std::size_t p = 0; p < pixels; ++p)
    for (int c = 0; c < 4; ++c) {
      const double mean = sum[p].s[c] * inv;
      out.image.pixels[p * 4 + c] = float(mean);
      const double var =
          rs.spp > 1 ? std::max(0.0, (sum_sq[p].s[c] * inv - mean * mean) * rs.spp / (rs.spp - 1.0)) : 0.0;
      out.variance.pixels[p * 4 + c] = float(var);
    }
  for (float v : out.image.pixels)
    if (!std::isfinite(v))
      throw DeviceError("the path tracer produced NaN or infinite pixels: a kernel bug; please report it");
  return out;
}

Image render_reference(const Device& device, const Scene& scene, std::size_t camera_index,
                       const PathTraceSettings& settings, const ProgressCallback& progress) {
  if (camera_index >= scene.cameras.size())
    throw InvalidArgument("the scene has " + std::to_string(scene.cameras.size()) + " camera(s); index " +
                          std::to_string(camera_index) + " does not exist (add \"cameras\" to the scene JSON)");
  PathTracer pt(device, scene);
  return pt.render(scene.cameras[camera_index], scene.lights, settings, progress).image;
}

}  // namespace relit
