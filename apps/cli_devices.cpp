// relit devices: what OpenCL sees, and whether relit's kernels build on each device.
#include "cli.hpp"

#include <relit/cl/device.hpp>
#include <relit/error.hpp>
#include <relit/nn/encodings.hpp>
#include <relit/nn/fully_fused_mlp.hpp>
#include <relit/render/volume_renderer.hpp>
#include <relit/version.hpp>

#include <nlohmann/json.hpp>

#include <cstdio>
#include <iomanip>
#include <iostream>
#include <sstream>

namespace relit::cli {

namespace {

std::string bytes_text(std::uint64_t bytes) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1);
  if (bytes >= (1ull << 30))
    s << bytes / double(1ull << 30) << " GiB";
  else if (bytes >= (1ull << 20))
    s << bytes / double(1ull << 20) << " MiB";
  else
    s << bytes / 1024.0 << " KiB";
  return s.str();
}

std::string wrap(const std::vector<std::string>& words, std::size_t indent, std::size_t width) {
  std::string out, line;
  for (const auto& w : words) {
    if (!line.empty() && line.size() + 1 + w.size() > width) {
      out += line + "\n" + std::string(indent, ' ');
      line.clear();
    }
    line += (line.empty() ? "" : " ") + w;
  }
  return out + line;
}

struct DevicesOptions {
  std::string selector;
  bool json = false;
  bool check = true;
};

int run_devices(const DevicesOptions& o) {
  const auto infos = list_devices();
  nlohmann::json doc = {{"relit_version", relit::version()},
                        {"build_features", relit::build_features()},
                        {"devices", nlohmann::json::array()}};
  bool all_ok = true;
  if (!o.json)
    std::cout << "relit " << relit::version() << " (" << relit::build_features() << "): " << infos.size()
              << " OpenCL device(s)\n";
  const auto selected = Device::select_all(o.selector);
  for (const auto& device : selected) {
    const DeviceInfo& i = device.info();
    std::vector<ProgramCheck> checks;
    if (o.check) checks = check_programs(device);
    double seconds = 0;
    int failed = 0;
    for (const auto& c : checks) {
      seconds += c.seconds;
      failed += !c.ok;
    }
    all_ok = all_ok && failed == 0;
    // The MLP kernels a network with kernel_variant "auto" runs here (the work-group tile is lowered per
    // network where its activations would not fit the device's local memory).
    const nn::FullyFusedMLP::KernelChoice mlp = nn::FullyFusedMLP::default_kernels(i);
    const bool simd = mlp.variant == nn::FullyFusedMLP::Variant::Simd;
    // The hash-grid encoding's and the renderer's (kernel_variant "auto"; parameters before fitting a grid or
    // a renderer's samples per ray).
    const nn::HashGridEncoding::KernelChoice grid = nn::HashGridEncoding::default_kernels(i);
    const render::VolumeRenderer::KernelChoice renderer = render::VolumeRenderer::default_kernels(i);
    if (o.json) {
      nlohmann::json d = {{"index", i.index},
                          {"platform_index", i.platform_index},
                          {"device_index", i.device_index},
                          {"platform", i.platform_name},
                          {"platform_version", i.platform_version},
                          {"name", i.name},
                          {"vendor", i.vendor},
                          {"type", i.type},
                          {"version", i.version},
                          {"driver_version", i.driver_version},
                          {"opencl_c_version", i.opencl_c_version},
                          {"compute_units", i.compute_units},
                          {"max_clock_mhz", i.max_clock_mhz},
                          {"global_memory", i.global_memory},
                          {"max_allocation", i.max_allocation},
                          {"local_memory", i.local_memory},
                          {"local_memory_is_global", i.local_memory_is_global},
                          {"max_work_group_size", i.max_work_group_size},
                          {"fp64", i.fp64},
                          {"extensions", i.extensions},
                          {"mlp_kernels",
                           {{"variant", nn::FullyFusedMLP::variant_name(mlp.variant)},
                            {"parameters", simd ? mlp.blocking.str() : mlp.workgroup.str()},
                            {"source", mlp.source},
                            {"tuned", mlp.tuned}}},
                          {"encoding_kernels",
                           {{"variant", kernel_variant_name(grid.variant)},
                            {"parameters", grid.workgroup.str()},
                            {"source", grid.source},
                            {"tuned", grid.tuned}}},
                          {"renderer_kernels",
                           {{"variant", kernel_variant_name(renderer.variant)},
                            {"parameters", renderer.workgroup.str()},
                            {"source", renderer.source},
                            {"tuned", renderer.tuned}}}};
      if (o.check) {
        d["kernels"] = nlohmann::json::array();
        for (const auto& c : checks)
          d["kernels"].push_back({{"file", c.file}, {"ok", c.ok}, {"seconds", c.seconds}, {"error", c.error}});
      }
      doc["devices"].push_back(d);
      continue;
    }
    std::cout << "\n[" << i.index << "] " << i.name << "  (platform " << i.platform_index << ": " << i.platform_name
              << ", device " << i.device_index << "; RELIT_DEVICE=" << i.index << ")\n";
    auto row = [](const char* key, const std::string& value) {
      std::cout << "    " << std::left << std::setw(16) << key << value << '\n';
    };
    row("type", i.type + ", vendor " + i.vendor);
    row("OpenCL", i.version + "; " + i.opencl_c_version + "; driver " + i.driver_version);
    row("compute units", std::to_string(i.compute_units) + " @ " + std::to_string(i.max_clock_mhz) + " MHz");
    row("memory", bytes_text(i.global_memory) + " global, " + bytes_text(i.max_allocation) + " largest buffer, " +
                      bytes_text(i.local_memory) + " local" + (i.local_memory_is_global ? " (emulated in RAM)" : ""));
    row("work-groups", "up to " + std::to_string(i.max_work_group_size) + " items; preferred float vector width " +
                           std::to_string(i.preferred_vector_width_float));
    row("fp64", i.fp64 ? "yes" : "no");
    row("MLP kernels", mlp.str());
    row("grid kernels", grid.str());
    row("render kernels", renderer.str());
    row("extensions", wrap(i.extensions, 20, 100));
    if (o.check) {
      std::ostringstream s;
      s << std::fixed << std::setprecision(2);
      if (failed == 0) {
        s << "build OK (" << checks.size() << " programs, " << seconds << " s)";
        row("relit kernels", s.str());
      } else {
        s << "FAILED (" << failed << " of " << checks.size() << " programs)";
        row("relit kernels", s.str());
        for (const auto& c : checks)
          if (!c.ok) std::cout << "      " << c.file << ": " << c.error << '\n';
      }
    }
  }
  if (o.json) std::cout << doc.dump(2) << '\n';
  return all_ok ? 0 : 1;
}

}  // namespace

void add_devices_command(CLI::App& app) {
  auto o = std::make_shared<DevicesOptions>();
  auto* cmd =
      app.add_subcommand("devices", "list OpenCL platforms and devices, and check that relit's kernels build on each");
  cmd->add_option("--device,-d", o->selector,
                  "only devices matching this selector (index, platform:device, or name part)");
  cmd->add_flag("--json", o->json, "print JSON instead of a table");
  cmd->add_flag("!--no-check", o->check, "skip building relit's kernels");
  on_parsed(cmd, o, run_devices);
}

}  // namespace relit::cli
