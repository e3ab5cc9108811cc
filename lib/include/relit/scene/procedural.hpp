// Procedural media and shapes, deterministic from a seed (same seed, same grid, on every machine):
//   cloud   cumulus-like: a cluster of fBm-modulated blobs with a flat base
//   smoke   a rising plume that widens and swirls, thinning with height
//   blobs   several soft blobs, each with its own albedo (fills an albedo grid: spatially varying albedo)
//   spheres signed distance to a few spheres (solid)
//   torus   signed distance to a tilted torus (solid)
// Density grids hold values in [0, 1] that vanish near the box faces; the scene's density_scale sets the
// optical thickness.
#pragma once

#include <relit/scene/grid.hpp>

#include <string>
#include <vector>

namespace relit {

struct ProceduralMedium {
  Grid density;
  Grid albedo;  ///< 3 channels for `blobs`, empty otherwise
};

ProceduralMedium make_cloud(int resolution, unsigned seed);
ProceduralMedium make_smoke(int resolution, unsigned seed);
ProceduralMedium make_blobs(int resolution, unsigned seed);
Grid make_spheres_sdf(int resolution, unsigned seed);
Grid make_torus_sdf(int resolution, unsigned seed);

/// Names of the built-in media and solids.
const std::vector<std::string>& procedural_media();
const std::vector<std::string>& procedural_solids();

/// Fractal (fBm) value noise in about [0, 1], deterministic from the seed.
double fbm_noise(double x, double y, double z, unsigned seed, int octaves);

}  // namespace relit
