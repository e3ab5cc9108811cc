// Import of OpenVDB fog volumes (.vdb, e.g. the public bunny_cloud.vdb) into a dense density grid.
#pragma once

#include <relit/scene/grid.hpp>

#include <string>

namespace relit {

/// Reads float grid `grid_name` ("" = the first float grid, preferring one called "density") from `path`
/// and resamples it (trilinear, in index space) into a resolution^3 grid over [-1, 1]^3: the volume's
/// active bounding box is centred and scaled uniformly so its longest side spans `fill` of the box (leaving
/// an empty margin). Values are divided by the grid's maximum so they lie in [0, 1].
/// Throws IOError for a missing or corrupt file or a missing grid.
Grid load_vdb_density(const std::string& path, const std::string& grid_name, int resolution, float fill = 0.9f);

}  // namespace relit
