// OpenVDB fog-volume import: resample a sparse float grid into a dense grid over the scene box.
#include <relit/error.hpp>
#include <relit/scene/vdb.hpp>

#if RELIT_WITH_OPENVDB
#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>
#endif

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <type_traits>

namespace relit {

bool VdbInfo::has(const std::string& grid) const {
  for (const auto& g : grids)
    if (g.rfind(grid + " (", 0) == 0) return true;
  return false;
}

#if !RELIT_WITH_OPENVDB
namespace {
[[noreturn]] void fail_without_openvdb(const std::string& path) {
  if (!std::filesystem::exists(path)) throw IOError("OpenVDB file '" + path + "' does not exist");
  throw IOError("cannot read OpenVDB file '" + path +
                "': this relit was built without OpenVDB (RELIT_WITH_OPENVDB=OFF)");
}
}  // namespace

VdbInfo read_vdb_info(const std::string& path) { fail_without_openvdb(path); }
Grid load_vdb_world(const std::string& path, const std::string&, int) { fail_without_openvdb(path); }
Grid load_vdb_density(const std::string& path, const std::string&, int, float) { fail_without_openvdb(path); }

#else
namespace {

struct VdbFile {
  openvdb::GridPtrVecPtr grids;
  openvdb::MetaMap::Ptr metadata;
};

VdbFile read_vdb_file(const std::string& path) {
  if (!std::filesystem::exists(path)) throw IOError("OpenVDB file '" + path + "' does not exist");
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
  try {
    openvdb::io::File file(path);
    file.open(false);  // no delayed loading: the whole grid is read now, so errors surface here
    VdbFile out{file.getGrids(), file.getMetadata()};
    file.close();
    return out;
  } catch (const openvdb::Exception& e) {
    throw IOError("cannot read OpenVDB file '" + path + "': " + e.what() + " (is it a valid .vdb file?)");
  }
}

std::string listing_of(const VdbFile& f) {
  std::string listing;
  for (const auto& base : *f.grids)
    listing += (listing.empty() ? "" : ", ") + base->getName() + " (" + base->valueType() + ")";
  return listing.empty() ? "none" : listing;
}

// The float grid named `grid_name`, or ("") the first float grid, preferring one called "density"; null if none.
openvdb::FloatGrid::Ptr pick_float_grid(const VdbFile& f, const std::string& grid_name) {
  openvdb::FloatGrid::Ptr grid, first, density;
  for (const auto& base : *f.grids) {
    auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(base);
    if (!g) continue;
    if (!grid_name.empty() && g->getName() == grid_name) grid = g;
    if (!first) first = g;
    if (g->getName() == "density" && !density) density = g;
  }
  if (grid_name.empty()) grid = density ? density : first;
  return grid;
}

}  // namespace

VdbInfo read_vdb_info(const std::string& path) {
  const VdbFile f = read_vdb_file(path);
  VdbInfo info;
  for (const auto& base : *f.grids) info.grids.push_back(base->getName() + " (" + base->valueType() + ")");
  if (f.metadata)
    for (auto it = f.metadata->beginMeta(); it != f.metadata->endMeta(); ++it)
      info.metadata[it->first] = it->second->str();
  if (const auto grid = pick_float_grid(f, ""); grid && grid->hasUniformVoxels()) {
    const double voxel = grid->voxelSize()[0];
    if (voxel > 0) info.resolution = static_cast<int>(std::lround(2.0 / voxel));
  }
  return info;
}

Grid load_vdb_world(const std::string& path, const std::string& grid_name, int resolution) {
  if (resolution < 8 || resolution > 512) throw InvalidArgument("vdb resolution must lie in [8, 512]");
  const VdbFile f = read_vdb_file(path);
  Grid out;
  const auto fill = [&](const auto& grid, int channels) {
    out = Grid(resolution, resolution, resolution, channels);
    // The sampler keeps a reference to its accessor: a temporary one would be gone before the first sample.
    using Accessor = typename std::decay_t<decltype(*grid)>::ConstAccessor;
    const Accessor accessor = grid->getConstAccessor();
    openvdb::tools::GridSampler<Accessor, openvdb::tools::BoxSampler> sampler(accessor, grid->transform());
    for (int k = 0; k < resolution; ++k)
      for (int j = 0; j < resolution; ++j)
        for (int i = 0; i < resolution; ++i) {
          const Float3 p = out.centre(i, j, k);
          // Index positions within rounding of a voxel centre snap to it: a grid at this very resolution (as
          // relit export writes) reads back exactly, not blended with its neighbours by 1e-7.
          openvdb::Vec3d ip = grid->transform().worldToIndex(openvdb::Vec3d(p[0], p[1], p[2]));
          for (int c = 0; c < 3; ++c)
            if (std::abs(ip[c] - std::round(ip[c])) < 1e-4) ip[c] = std::round(ip[c]);
          const auto v = sampler.isSample(ip);
          if constexpr (std::is_same_v<std::decay_t<decltype(v)>, float>) {
            out.at(i, j, k) = v;
          } else {
            for (int c = 0; c < 3; ++c) out.at(i, j, k, c) = v[c];
          }
        }
  };
  if (const auto grid = pick_float_grid(f, grid_name)) {
    fill(grid, 1);
    return out;
  }
  for (const auto& base : *f.grids)
    if (base->getName() == grid_name)
      if (const auto g = openvdb::gridPtrCast<openvdb::Vec3SGrid>(base)) {
        fill(g, 3);
        return out;
      }
  throw IOError("OpenVDB file '" + path + "' has no float or vec3s grid" +
                (grid_name.empty() ? "" : " named '" + grid_name + "'") + "; its grids: " + listing_of(f));
}

Grid load_vdb_density(const std::string& path, const std::string& grid_name, int resolution, float fill) {
  if (resolution < 8 || resolution > 512) throw InvalidArgument("vdb resolution must lie in [8, 512]");
  if (!(fill > 0.1f && fill <= 1.0f)) throw InvalidArgument("vdb fill must lie in (0.1, 1]");
  const VdbFile f = read_vdb_file(path);
  const openvdb::FloatGrid::Ptr grid = pick_float_grid(f, grid_name);
  if (!grid)
    throw IOError("OpenVDB file '" + path + "' has no float grid" +
                  (grid_name.empty() ? "" : " named '" + grid_name + "'") + "; its grids: " + listing_of(f));

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

#endif  // RELIT_WITH_OPENVDB

}  // namespace relit
