// Import of OpenVDB fog volumes (.vdb, e.g. the public bunny_cloud.vdb) into a dense density grid.
#pragma once

#include <relit/scene/grid.hpp>

#include <map>
#include <string>
#include <vector>

namespace relit {

/// Reads float grid `grid_name` ("" = the first float grid, preferring one called "density") from `path`
/// and resamples it (trilinear, in index space) into a resolution^3 grid over [-1, 1]^3: the volume's
/// active bounding box is centred and scaled uniformly so its longest side spans `fill` of the box (leaving
/// an empty margin). Values are divided by the grid's maximum so they lie in [0, 1].
/// Throws IOError for a missing or corrupt file or a missing grid.
Grid load_vdb_density(const std::string& path, const std::string& grid_name, int resolution, float fill = 0.9f);

/// What a .vdb file holds: its grids ("name (type)") and its file-level metadata as text.
struct VdbInfo {
  std::vector<std::string> grids;
  std::map<std::string, std::string> metadata;
  /// Voxels per side of the box [-1, 1]^3 in the first float grid's transform (2 / voxel size, rounded), or 0
  /// when that grid has no uniform voxel size.
  int resolution = 0;
  bool has(const std::string& grid) const;
};
/// Reads the grid list and metadata of `path`; IOError for a missing or corrupt file.
VdbInfo read_vdb_info(const std::string& path);

/// Samples grid `grid_name` ("" = as load_vdb_density picks) as placed in the world by its own transform, at
/// the voxel centres of a resolution^3 grid over [-1, 1]^3 (trilinear), keeping its values: a float grid gives
/// 1 channel, a vec3 grid 3 (the grids relit export writes: density as extinction per scene unit, albedo).
/// Voxels outside the volume are 0. Throws IOError for a missing file or grid.
Grid load_vdb_world(const std::string& path, const std::string& grid_name, int resolution);

}  // namespace relit
