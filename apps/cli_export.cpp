// relit export: a trained run's learned medium for other tools (OpenVDB grids; docs/interop.md).
#include "cli.hpp"

#include <relit/cl/device.hpp>
#include <relit/error.hpp>
#include <relit/method/export.hpp>
#include <relit/method/model_io.hpp>

#include <filesystem>
#include <iostream>

namespace fs = std::filesystem;

namespace relit::cli {

namespace {

struct ExportOptions {
  std::string run, vdb, device;
  int resolution = 128;
  float threshold = 0.01f;
};

// The run's name: its folder's (a trailing slash allowed).
std::string run_name(const std::string& run) {
  fs::path p = fs::path(run).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  return p.filename().string();
}

int run_export(const ExportOptions& o) {
  if (o.vdb.empty()) throw InvalidArgument("relit export: say what to write: --vdb OUT.vdb");
  if (!fs::is_directory(o.run)) throw IOError("run folder '" + o.run + "' does not exist");
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
  return 0;
}

}  // namespace

void add_export_command(CLI::App& app) {
  auto o = std::make_shared<ExportOptions>();
  auto* cmd = app.add_subcommand("export", "export a trained run's learned medium for other tools (OpenVDB)");
  cmd->add_option("run", o->run, "run folder written by relit train")->required();
  cmd->add_option("--vdb", o->vdb,
                  "write an OpenVDB file: sparse grids 'density' (extinction per scene unit), 'albedo' (vec3) and "
                  "'g' over the box [-1, 1]^3");
  cmd->add_option("--resolution", o->resolution, "voxels per side of the box")
      ->check(integer_in(8, 512))
      ->capture_default_str();
  cmd->add_option("--threshold", o->threshold,
                  "voxels whose extinction (1 / scene unit) is at or below this stay empty in the OpenVDB grids")
      ->check(number_in(0, 1e9))
      ->capture_default_str();
  cmd->add_option("--device,-d", o->device, "OpenCL device selector (index, platform:device, or name part)");
  cmd->final_callback([o] {
    if (const int code = run_export(*o)) throw CLI::RuntimeError(code);
  });
}

}  // namespace relit::cli
