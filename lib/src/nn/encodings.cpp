// Registration of the encodings (one registry entry per encoding type): the JSON keys, their defaults,
// ranges and descriptions, which docs/config.md is generated from.
#include <relit/nn/encodings.hpp>
#include <relit/nn/registry.hpp>

namespace relit::nn {

namespace {

std::unique_ptr<Encoding> make_identity(config::Reader& r, std::uint32_t n_dims) {
  IdentityEncoding::Options o;
  o.scale = r.number("scale", 1.0f, -1e6f, 1e6f, "multiplies every input");
  o.offset = r.number("offset", 0.0f, -1e6f, 1e6f, "added after scaling");
  return std::make_unique<IdentityEncoding>(n_dims, o);
}

std::unique_ptr<Encoding> make_frequency(config::Reader& r, std::uint32_t n_dims) {
  FrequencyEncoding::Options o;
  o.n_frequencies = r.uint("n_frequencies", 10, 1, 24,
                           "octaves k = 0..n-1 of sin/cos(2^k pi x); the highest frequency is 2^(n-1) "
                           "(NeRF positions: 10, directions: 5)");
  o.include_input = r.boolean("include_input", false, "also output the raw inputs first (NeRF does)");
  return std::make_unique<FrequencyEncoding>(n_dims, o);
}

std::unique_ptr<Encoding> make_sh(config::Reader& r, std::uint32_t n_dims) {
  SphericalHarmonicsEncoding::Options o;
  o.degree = r.uint("degree", 4, 1, SphericalHarmonicsEncoding::kMaxDegree,
                    "bands l = 0..degree-1, degree^2 outputs (tiny-cuda-nn's convention; l_max = degree - 1)");
  if (n_dims != 3)
    r.fail("", "SphericalHarmonics encodes 3-D unit directions, but it was given " + std::to_string(n_dims) +
                   " input dims");
  return std::make_unique<SphericalHarmonicsEncoding>(n_dims, o);
}

std::unique_ptr<Encoding> make_hash_grid(config::Reader& r, std::uint32_t n_dims) {
  HashGridEncoding::Options o;
  o.n_levels = r.uint("n_levels", 16, 1, 32, "number of resolution levels");
  o.n_features_per_level = r.uint_choice("n_features_per_level", 2, {1, 2, 4, 8}, "features per level and entry");
  o.log2_hashmap_size = r.uint("log2_hashmap_size", 19, 10, 24, "log2 of the table entries per level (T)");
  o.base_resolution = r.uint("base_resolution", 16, 2, 1u << 20, "cells per axis of the coarsest level");
  o.per_level_scale =
      r.number("per_level_scale", 2.0f, 1.0f, 8.0f, "growth factor of the resolution from one level to the next");
  o.gradient_ranges = r.uint("gradient_ranges", 0, 0, 4096,
                             "table ranges per level in the gradient pass, for parallelism (0: per device, 1 on "
                             "CPUs); the gradient is bit-for-bit the same for any value");
  o.kernel_variant = r.choice("kernel_variant", "auto", {"auto", "simd", "workgroup"},
                              "which kernels run the encoding: auto (the device's table: SIMD kernels on CPUs, "
                              "work-group kernels on GPUs), simd or workgroup; RELIT_ENCODING_VARIANT overrides it "
                              "(docs/encodings.md)");
  if (n_dims != 2 && n_dims != 3)
    r.fail("", "HashGrid encodes 2-D or 3-D positions in [0, 1]^d, but it was given " + std::to_string(n_dims) +
                   " input dims");
  try {
    return std::make_unique<HashGridEncoding>(n_dims, o);
  } catch (const InvalidArgument& e) {
    if (dynamic_cast<const ConfigError*>(&e)) throw;
    r.fail("", e.what());
  }
}

std::unique_ptr<Encoding> make_composite(config::Reader& r, std::uint32_t n_dims) {
  const Json nested = r.sub("nested", Json::array({Json{{"type", "Identity"}}}), "array",
                            "nested encodings, each an encoding object with \"n_dims_to_encode\" (the last may "
                            "omit it and take the remaining dims)");
  if (!nested.is_array() || nested.empty())
    r.fail("nested", "must be a non-empty list of encoding objects, got " + nested.dump());
  std::vector<CompositeEncoding::Part> parts;
  Json resolved = Json::array();
  std::uint32_t used = 0;
  for (std::size_t i = 0; i < nested.size(); ++i) {
    const std::string ptr = r.pointer("nested") + "/" + std::to_string(i);
    Json item = nested[i];
    if (!item.is_object()) throw ConfigError(ptr, "must be an encoding object, got " + item.dump());
    std::uint32_t dims = n_dims > used ? n_dims - used : 0;
    if (auto it = item.find("n_dims_to_encode"); it != item.end()) {
      const bool integral = it->is_number_integer() || it->is_number_unsigned();
      if (!integral || it->get<std::int64_t>() < 1 ||
          it->get<std::int64_t>() > static_cast<std::int64_t>(n_dims - used))
        throw ConfigError(ptr + "/n_dims_to_encode", "must be an integer in [1, " + std::to_string(n_dims - used) +
                                                         "] (the input dims not yet encoded), got " + it->dump());
      dims = it->get<std::uint32_t>();
      item.erase("n_dims_to_encode");
    } else if (i + 1 != nested.size()) {
      throw ConfigError(ptr, "missing \"n_dims_to_encode\" (only the last nested encoding may omit it)");
    }
    if (dims == 0) throw ConfigError(ptr, "no input dims are left for this nested encoding");
    Json res;
    parts.push_back({encodings().create(item, ptr, dims, &res), dims});
    res["n_dims_to_encode"] = dims;
    resolved.push_back(res);
    used += dims;
  }
  if (used != n_dims)
    r.fail("nested", "the nested encodings take " + std::to_string(used) + " input dims, but the input has " +
                         std::to_string(n_dims));
  r.set_resolved("nested", resolved);
  return std::make_unique<CompositeEncoding>(std::move(parts), Json{{"type", "Composite"}, {"nested", resolved}});
}

}  // namespace

void register_encodings(EncodingRegistry& registry) {
  registry.add("Identity", "passes the inputs through, optionally scaled and offset", make_identity);
  registry.add("Frequency", "NeRF positional encoding: sin and cos of 2^k pi x, k = 0..n_frequencies-1",
               make_frequency);
  registry.add("SphericalHarmonics", "real spherical harmonics of a unit direction (Zheng et al. 2021, eq. 2)",
               make_sh);
  registry.add("HashGrid", "multiresolution hash encoding (instant-ngp) of positions in [0, 1]^d", make_hash_grid);
  registry.add("Composite", "nested encodings over consecutive input dims, outputs concatenated", make_composite);
}

}  // namespace relit::nn
