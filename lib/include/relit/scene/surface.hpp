// Surface: a solid object given by a signed-distance grid (negative inside, in scene units), shaded with
// the BRDF of docs/design.md §4.4 (kernels/brdf.clh): UE4/Karis GGX (alpha = roughness^2, Schlick-GGX G with
// k = (r+1)^2/8, Schlick F with F0 = 0.04 in its spherical-Gaussian form) plus Lambert base_colour/pi scaled
// by the energy the specular lobe leaves, so that the BRDF conserves energy (docs/method.md, "The BRDF").
#pragma once

#include <relit/scene/grid.hpp>

namespace relit {

struct Surface {
  Grid sdf;                             ///< 1 channel, signed distance
  Float3 base_color{0.8f, 0.8f, 0.8f};  ///< diffuse albedo
  float roughness = 0.4f;               ///< in [0.02, 1]

  void validate() const;
};

}  // namespace relit
