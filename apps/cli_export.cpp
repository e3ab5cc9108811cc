// relit export: a trained run's learned medium for other tools (OpenVDB grids, a Mitsuba 3 scene;
// docs/interop.md).
#include "cli.hpp"

#include <relit/cl/device.hpp>
#include <relit/config.hpp>
#include <relit/dataset.hpp>
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/method/export.hpp>
#include <relit/method/model_io.hpp>

#include <filesystem>
#include <iostream>

namespace fs = std::filesystem;

namespace relit::cli {

namespace {

struct ExportOptions {
  std::string run, vdb, mitsuba, device;
  int resolution = 128;
  std::uint32_t spp = 256;
  float threshold = 0.01f;
};

// The run's name: its folder's (a trailing slash allowed).
std::string run_name(const std::string& run) {
  fs::path p = fs::absolute(run).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  return p.filename().string();
}

// The Mitsuba scene's camera and light: the first test view of the run's dataset (else its first view); when
// the dataset cannot be read, relit render's default camera and light, with a warning.
void dataset_view(const std::string& run, method::MitsubaExportSettings& s) {
  std::string dataset;
  try {
    const Json config = parse_json(io::read_file((fs::path(run) / "config.json").string()), "the run's config.json");
    dataset = config.value("dataset", std::string());
    if (dataset.empty()) throw IOError("config.json names no dataset");
    const DatasetDescription desc = read_dataset(dataset);
    if (desc.splits.empty()) throw IOError("the dataset has no views");
    const auto it = desc.splits.find("test");
    const auto& frames = it != desc.splits.end() && !it->second.empty() ? it->second : desc.splits.begin()->second;
    if (frames.empty()) throw IOError("the dataset has no views");
    s.camera = frames.front().camera;
    s.light = frames.front().light;
    std::cerr << "relit export: the Mitsuba scene sees the " << (it != desc.splits.end() ? "first test" : "first")
              << " view of " << dataset << "\n";
  } catch (const Error& e) {
    s.camera = Camera::look_at({0, -4, 1}, {0, 0, 0}, {0, 0, 1}, 0.8f, 128, 128);
    s.light = PointLight{{0, -3, 3}, {600, 600, 600}};
    std::cerr << "relit export: warning: the run's dataset" << (dataset.empty() ? "" : " '" + dataset + "'")
              << " gives no camera (" << e.what() << "); the Mitsuba scene uses relit render's default camera "
              << "(eye 0 -4 1) and light (0 -3 3, 600 W/sr)\n";
  }
}

int run_export(const ExportOptions& o) {
  if (o.vdb.empty() && o.mitsuba.empty())
    throw InvalidArgument("relit export: say what to write: --vdb OUT.vdb and/or --mitsuba DIR");
  if (!fs::is_directory(o.run)) throw IOError("run folder '" + o.run + "' does not exist");
  if (!o.mitsuba.empty() && fs::exists(o.mitsuba))  // before anything is written
    throw IOError("cannot write the Mitsuba scene to '" + o.mitsuba +
                  "': it exists (choose a new folder or remove it)");
  const Device device = Device::select(o.device);
  const auto model = method::load_model(device, (fs::path(o.run) / "checkpoint.relit").string());
  if (!o.vdb.empty()) {
    method::VdbExportSettings s;
    s.resolution = o.resolution;
    s.threshold = o.threshold;
    s.run = run_name(o.run);
    const auto stats = method::export_vdb(*model, o.vdb, s);
    std::cout << "OpenVDB grids (density, albedo, g; " << stats.active_voxels << " active voxels of " << o.resolution
              << "^3, max sigma " << stats.max_sigma << ") written to " << o.vdb << "\n";
  }
  if (!o.mitsuba.empty()) {
    method::MitsubaExportSettings s;
    s.resolution = o.resolution;
    s.spp = o.spp;
    s.run = run_name(o.run);
    dataset_view(o.run, s);
    method::export_mitsuba(*model, o.mitsuba, s);
    std::cout << "Mitsuba 3 scene (scene.xml, density.vol, albedo.vol) written to " << o.mitsuba
              << "; render it with: mitsuba -m scalar_rgb " << (fs::path(o.mitsuba) / "scene.xml").string() << "\n";
  }
  return 0;
}

}  // namespace

void add_export_command(CLI::App& app) {
  auto o = std::make_shared<ExportOptions>();
  auto* cmd =
      app.add_subcommand("export", "export a trained run's learned medium for other tools (OpenVDB, Mitsuba 3)");
  cmd->add_option("run", o->run, "run folder written by relit train")->required();
  cmd->add_option("--vdb", o->vdb,
                  "write an OpenVDB file: sparse grids 'density' (extinction per scene unit), 'albedo' (vec3) and "
                  "'g' over the box [-1, 1]^3");
  cmd->add_option("--mitsuba", o->mitsuba,
                  "write a Mitsuba 3 scene into this new folder: density.vol, albedo.vol and scene.xml with the "
                  "dataset's first test camera and light and the volpath integrator");
  cmd->add_option("--spp", o->spp, "samples per pixel of the Mitsuba scene's sampler")
      ->check(integer_in(1, 1048576))
      ->capture_default_str();
  cmd->add_option("--resolution", o->resolution, "voxels per side of the box")
      ->check(integer_in(8, 512))
      ->capture_default_str();
  cmd->add_option("--threshold", o->threshold,
                  "voxels whose extinction (1 / scene unit) is at or below this stay empty in the OpenVDB grids")
      ->check(number_in(0, 1e9))
      ->capture_default_str();
  add_device_option(cmd, o->device);
  on_parsed(cmd, o, run_export);
}

}  // namespace relit::cli
