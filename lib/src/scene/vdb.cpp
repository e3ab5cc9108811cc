// OpenVDB fog-volume import: resample a sparse float grid into a dense grid over the scene box.
#include <relit/error.hpp>
#include <relit/scene/vdb.hpp>

#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>

#include <algorithm>
#include <filesystem>
#include <mutex>

namespace relit {

Grid load_vdb_density(const std::string& path, const std::string& grid_name, int resolution, float fill) {
  if (resolution < 8 || resolution > 512) throw InvalidArgument("vdb resolution must lie in [8, 512]");
  if (!(fill > 0.1f && fill <= 1.0f)) throw InvalidArgument("vdb fill must lie in (0.1, 1]");
  if (!std::filesystem::exists(path)) throw IOError("OpenVDB file '" + path + "' does not exist");
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });

  openvdb::FloatGrid::Ptr grid;
  std::vector<std::string> names;
  try {
    openvdb::io::File file(path);
    file.open(false);  // no delayed loading: the whole grid is read now, so errors surface here
    openvdb::GridPtrVecPtr grids = file.getGrids();
    file.close();
    openvdb::FloatGrid::Ptr first, density;
    for (const auto& base : *grids) {
      names.push_back(base->getName() + " (" + base->valueType() + ")");
      auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(base);
      if (!g) continue;
      if (!grid_name.empty() && g->getName() == grid_name) grid = g;
      if (!first) first = g;
      if (g->getName() == "density" && !density) density = g;
    }
    if (grid_name.empty()) grid = density ? density : first;
  } catch (const openvdb::Exception& e) {
    throw IOError("cannot read OpenVDB file '" + path + "': " + e.what() + " (is it a valid .vdb file?)");
  }
  std::string listing;
  for (const auto& n : names) listing += (listing.empty() ? "" : ", ") + n;
  if (!grid)
    throw IOError("OpenVDB file '" + path + "' has no float grid" +
                  (grid_name.empty() ? "" : " named '" + grid_name + "'") +
                  "; its grids: " + (listing.empty() ? "none" : listing));

  const openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
  if (box.empty()) throw IOError("OpenVDB grid '" + grid->getName() + "' in '" + path + "' has no active voxels");
  const openvdb::Vec3d lo = box.min().asVec3d() - 0.5, hi = box.max().asVec3d() + 0.5;
  const openvdb::Vec3d extent = hi - lo, mid = (lo + hi) * 0.5;
  const double longest = std::max({extent.x(), extent.y(), extent.z()});
  // World [-1, 1] maps to index space so that the longest side spans `fill` of the box.
  const double index_per_unit = longest / (2.0 * fill);

  Grid out(resolution, resolution, resolution, 1);
  // The sampler keeps a reference to its accessor: a temporary one would be gone before the first sample.
  const openvdb::FloatGrid::ConstAccessor accessor = grid->getConstAccessor();
  openvdb::tools::GridSampler<openvdb::FloatGrid::ConstAccessor, openvdb::tools::BoxSampler> sampler(accessor,
                                                                                                     grid->transform());
  float vmax = 0.0f;
  for (int k = 0; k < resolution; ++k)
    for (int j = 0; j < resolution; ++j)
      for (int i = 0; i < resolution; ++i) {
        const Float3 p = out.centre(i, j, k);
        const openvdb::Vec3d ip = mid + openvdb::Vec3d(p[0], p[1], p[2]) * index_per_unit;
        const float v = std::max(0.0f, sampler.isSample(ip));
        out.at(i, j, k) = v;
        vmax = std::max(vmax, v);
      }
  if (!(vmax > 0.0f))
    throw IOError("OpenVDB grid '" + grid->getName() + "' in '" + path + "' holds no positive density");
  for (auto& v : out.values) v /= vmax;
  return out;
}

}  // namespace relit
