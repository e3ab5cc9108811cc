// The method of Zheng, Singh, Seidel (NeurIPS 2021), "ours", and its solid-object variant "ours_brdf":
// MediumModels (relit/method/medium.hpp). Ours has every part at its default: the HG phase function with
// g = 0.95 tanh(raw), the light-conditioned SH indirect head and the environment's c_env head, uniform samples
// along each ray; Ours + BRDF replaces the phase function by the BRDF.
//
// The model is configured by the "model" object of a run config (docs/method.md; keys in docs/config.md).
#pragma once

#include <relit/method/medium.hpp>

namespace relit::method {

class Ours : public MediumModel {
 public:
  /// Builds the networks from the "model" config object (at JSON pointer `pointer`); unknown keys and bad
  /// values are ConfigErrors naming the pointer.
  Ours(const Device& device, const Json& config, const std::string& pointer = "/model");
  /// Every key of the model config, per JSON object (for docs/config.md).
  static void describe(config::Docs& docs);
  /// Reads a model config without a device (ConfigErrors as the constructor); the resolved config.
  static Json check(const Json& config, const std::string& pointer) { return Ours().check_keys(config, pointer); }
  static MethodParts method_parts() { return {}; }
  std::string method() const override { return "ours"; }

 private:
  Ours() : MediumModel(method_parts()) {}
};

/// "Ours + BRDF" for solid objects, the "ours_brdf" method: Ours with the UE4/Karis BRDF (kernels/brdf.clh)
/// in place of the phase function; the property net predicts σ, the diffuse albedo, the roughness and a normal
/// (normalised by the renderer). SH l_max defaults to 1.
class OursBrdf : public MediumModel {
 public:
  OursBrdf(const Device& device, const Json& config, const std::string& pointer = "/model");
  static void describe(config::Docs& docs);
  static Json check(const Json& config, const std::string& pointer) { return OursBrdf().check_keys(config, pointer); }
  static MethodParts method_parts() {
    MethodParts p;
    p.scattering = Scattering::brdf();
    p.default_sh = "1";
    return p;
  }
  std::string method() const override { return "ours_brdf"; }

 private:
  OursBrdf() : MediumModel(method_parts()) {}
};

}  // namespace relit::method
