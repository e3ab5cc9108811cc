// Medium: a heterogeneous participating medium in the scene box [-1, 1]^3.
//
//   sigma_t(x) = density_scale * density(x)      (extinction, 1/unit length; trilinear in the density grid)
//   albedo(x)  = albedo_grid(x) if present, else the constant albedo (RGB, scattering / extinction)
//   phase      = Henyey-Greenstein with asymmetry g in (-1, 1) (docs/design.md §4.1: directions point away, +2g form)
#pragma once

#include <relit/scene/grid.hpp>

namespace relit {

struct Medium {
  Grid density;                     ///< 1 channel, usually in [0, 1]
  float density_scale = 1.0f;       ///< multiplies the grid
  Float3 albedo{0.9f, 0.9f, 0.9f};  ///< used when albedo_grid is empty
  Grid albedo_grid;                 ///< 3 channels, or empty
  float g = 0.0f;

  /// Throws InvalidArgument when a value is out of range (negative density, g outside (-1, 1), ...).
  void validate() const;
};

}  // namespace relit
