// Helpers shared by the methods' sources (private to the library).
#pragma once

#include <relit/cl/buffer.hpp>
#include <relit/config.hpp>
#include <relit/error.hpp>
#include <relit/method/medium.hpp>

#include <algorithm>
#include <cstdint>
#include <string>

namespace relit::method::detail {

/// A network JSON with the output heads the model needs; the user may not set them.
inline Json with_heads(Json network, const std::string& pointer, const Json& heads) {
  if (!network.is_object()) throw ConfigError(pointer, "must be a network object, got " + network.dump());
  for (const char* key : {"output_heads", "output_activation"})
    if (network.contains(key))
      throw ConfigError(pointer + "/" + key, "is set by the model (its heads are fixed by the method); remove it");
  network["output_heads"] = heads;
  return network;
}

/// A network's resolved JSON without the heads the model set (what a config gives back).
inline Json strip_heads(Json network) {
  network.erase("output_heads");
  network.erase("output_activation");
  return network;
}

/// The number of a pass's first rays that make up `fraction` of them (at least one).
inline std::uint32_t rays_in_share(std::uint32_t n_rays, float fraction) {
  return std::max<std::uint32_t>(1, std::min(n_rays, static_cast<std::uint32_t>(n_rays * double(fraction) + 0.5)));
}

/// The visibility net's training subset of a pass: the first rays_in_share(batch, fraction) rays of the global
/// batch (`batch_rays`, 0: the pass's n_rays), and how many of them the pass holds (its `share`: every
/// stride-th ray, so the subset's rays are the first `local` rays of the pass).
struct Subset {
  std::uint32_t local = 0, global = 0;
  std::uint32_t batch = 0;  // the global batch the subset is a share of
};
inline Subset visibility_subset(std::uint32_t n_rays, float fraction, parallel::Share share, std::uint32_t batch_rays) {
  const std::uint32_t batch = batch_rays ? batch_rays : n_rays;
  const std::uint32_t global = rays_in_share(batch, fraction);
  return {std::min(n_rays, share.count(global)), global, batch};
}

/// Grows `b` to at least `count` floats (scratch reused across passes).
inline void ensure_size(Buffer<float>& b, const Device& device, std::size_t count) {
  if (b.size() < count) b = Buffer<float>(device, count);
}

// The visibility net's defaults: its position and direction encodings and its MLP (NeRV's V-and-depth net
// starts from the same encodings).
inline Json default_visibility() {
  return {{"position_encoding",
           {{"type", "HashGrid"},
            {"n_levels", 8},
            {"n_features_per_level", 2},
            {"log2_hashmap_size", 15},
            {"base_resolution", 8},
            {"per_level_scale", 1.5}}},
          {"direction_encoding", {{"type", "SphericalHarmonics"}, {"degree", 4}}},
          {"network", {{"type", "FullyFusedMLP"}, {"n_neurons", 64}, {"n_hidden_layers", 2}}}};
}

// Columns of the SH head's input: the features, the light position, V toward the light, exp(-k τ) toward it.
inline std::uint32_t indirect_input_cols(const MediumSettings& s) {
  return s.n_features + (s.light_conditioned ? 3 : 0) + (s.indirect_visibility_input ? 1 : 0) +
         (s.indirect_optical_depth > 0.0f ? 1 : 0);
}

// Reads an object-valued key of `r` with its own Reader over the given sub-keys (each a component JSON,
// defaulting to the entry of `defaults`).
struct SubConfig {
  config::Reader reader;
  config::Docs* docs;
  std::string key;
  SubConfig(config::Reader& parent, const std::string& key_, const Json& defaults, const std::string& description,
            config::Docs* docs_out)
      : reader(parent.sub(key_, defaults, "object", description), parent.pointer(key_), key_),
        docs(docs_out),
        key(key_) {}
  Json component(const std::string& key, const Json& defaults, const std::string& description) {
    return reader.sub(key, defaults.at(key), "component", description);
  }
  /// Rejects unknown keys and records the object's keys for the config reference.
  void finish() {
    reader.finish();
    if (docs) docs->emplace_back(reader.pointer(), reader.docs());
  }
  /// finish(), and the object's resolved keys become `parent`'s value of the key.
  void finish_into(config::Reader& parent) {
    finish();
    parent.set_resolved(key, reader.resolved());
  }
};

}  // namespace relit::method::detail
