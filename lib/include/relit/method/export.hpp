// Exporting a learned medium to other tools (docs/interop.md): its properties sampled at the voxel centres of
// a grid over the scene box, written as OpenVDB grids (Blender, Houdini; relit's own scene loader reads them
// back) or as a Mitsuba 3 scene (.vol grids and scene.xml).
//
//   auto model = relit::method::load_model(device, "runs/cloud/checkpoint.relit");
//   relit::method::VdbExportSettings settings;
//   settings.run = "cloud";
//   relit::method::export_vdb(*model, "cloud.vdb", settings);   // density (extinction), albedo, g
#pragma once

#include <relit/method/model.hpp>
#include <relit/scene/camera.hpp>
#include <relit/scene/light.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace relit::method {

/// A medium sampled on a resolution^3 grid over [-1, 1]^3: voxel (i, j, k) (x fastest) at the world position
/// -1 + (i + 0.5) 2 / resolution per axis, as relit::Grid.
struct MediumSamples {
  int resolution = 0;
  std::vector<float> sigma;   ///< extinction σ, 1 / scene unit (what the renderer integrates)
  std::vector<float> albedo;  ///< single-scattering albedo, 3 per voxel (RGB)
  std::vector<float> g;       ///< Henyey-Greenstein asymmetry (0 for an isotropic method)
};

/// The learned medium of `model` at the voxel centres (its property network, as rendering sees it).
/// InvalidArgument for a model that is no participating medium (ours_brdf's solids have no albedo and phase)
/// or a resolution outside [8, 512].
MediumSamples sample_medium(const Model& model, int resolution);

/// How export_vdb writes the grids.
struct VdbExportSettings {
  int resolution = 128;     ///< voxels per side of the box [-1, 1]^3, in [8, 512]
  float threshold = 0.01f;  ///< voxels with σ at or below it (1 / scene unit) stay inactive (σ = 0)
  std::string run;          ///< the run's name, stored as file metadata "relit_run"
};

/// What export_vdb wrote.
struct VdbExportStats {
  std::uint64_t active_voxels = 0;
  float max_sigma = 0.0f;
  float mean_g = 0.0f;  ///< σ-weighted over the active voxels (file metadata "relit_mean_g")
};

/// Writes `path` (atomically) with three sparse grids over the active voxels (σ above the threshold): "density"
/// (float, a fog volume, σ in 1 / scene unit), "albedo" (vec3s) and "g" (float), with the transform that puts
/// them in the box [-1, 1]^3 (voxel size 2 / resolution). File metadata: relit_run, relit_method,
/// relit_resolution, relit_threshold, relit_mean_g, relit_units. IOError naming the path when it cannot be
/// written; `relit generate --scene PATH` (Scene::builtin_or_file) reads it back.
VdbExportStats export_vdb(const Model& model, const std::string& path, const VdbExportSettings& settings = {});

/// How export_mitsuba writes the scene.
struct MitsubaExportSettings {
  int resolution = 128;  ///< voxels per side of the box, in [8, 512]
  Camera camera;         ///< the scene's sensor (e.g. the dataset's first test view)
  PointLight light;      ///< the scene's point emitter
  std::uint32_t spp = 256;
  std::string run;  ///< named in a comment of scene.xml
};

/// What export_mitsuba wrote.
struct MitsubaExportStats {
  float max_sigma = 0.0f;
  float mean_g = 0.0f;  ///< σ-weighted over the grid: Mitsuba's hg phase takes one g
};

/// Writes folder `dir` (which must not exist; built under a temporary name and renamed once complete):
/// density.vol (σ, 1 / scene unit), albedo.vol (RGB) — Mitsuba 3's binary grids, x fastest — and scene.xml:
/// a `cube` (the box [-1, 1]^3) with a `null` BSDF and a `heterogeneous` interior medium (sigma_t and albedo
/// from the grids, scale 1, `hg` with the σ-weighted mean g), the camera as a `perspective` sensor
/// (box-filtered `hdrfilm`), the light as a `point` emitter and the `volpath` integrator. `mitsuba
/// DIR/scene.xml` renders it. IOError naming the folder when it exists or cannot be written.
MitsubaExportStats export_mitsuba(const Model& model, const std::string& dir, const MitsubaExportSettings& settings);

}  // namespace relit::method
