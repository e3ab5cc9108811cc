// Helpers shared by the C++ tests.
#pragma once

#include <relit/relit.hpp>

#include <gtest/gtest.h>

#include <relit/io/file.hpp>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <optional>
#include <string>
#include <vector>

namespace relit::test {

/// The devices under test: RELIT_TEST_DEVICES (a selector, like RELIT_DEVICE) or every device.
/// Throws (failing the test) when there is none: the suite must never pass without a device.
inline std::vector<Device> devices_under_test() {
  const char* sel = std::getenv("RELIT_TEST_DEVICES");
  return Device::select_all(sel ? sel : "all");
}

inline constexpr double kPi = 3.14159265358979323846;

/// The first device under test.
inline Device test_device() { return devices_under_test().front(); }

/// True when the kernel tests run at their smallest sizes: on Oclgrind, the OpenCL simulator that checks every
/// memory access and barrier (tests/check_oclgrind.cmake; thousands of times slower than a CPU device), or
/// when RELIT_TEST_TINY is set. Tests that have large cases skip those then, and keep the small ones.
inline bool tiny_sizes() {
  static const bool tiny = [] {
    if (std::getenv("RELIT_TEST_TINY")) return true;
    for (const Device& d : devices_under_test())
      if (d.info().platform_name.find("Oclgrind") != std::string::npos) return true;
    return false;
  }();
  return tiny;
}

/// The method tests' small smooth networks (frequency encodings, no hash grid), so that finite differences
/// are meaningful.
inline Json tiny_mlp() { return {{"type", "FullyFusedMLP"}, {"n_neurons", 16}, {"n_hidden_layers", 1}}; }
inline Json tiny_frequency() { return {{"type", "Frequency"}, {"n_frequencies", 2}, {"include_input", true}}; }

/// `config` with every FullyFusedMLP's hidden activation "None": ReLU kinks lie within any useful difference
/// step of most first-layer weights (hundreds of samples per batch), which biases central differences by half
/// the kink's slope change, so the gradient checks run on networks that are smooth (linear hidden layers; the
/// heads' activations and the renderer stay nonlinear). The ReLU backward pass has its own reference checks
/// (test_fully_fused_mlp.cpp).
inline Json smooth_networks(Json config) {
  if (config.is_object()) {
    if (config.value("type", "") == "FullyFusedMLP") config["activation"] = "None";
    for (auto& [key, value] : config.items()) value = smooth_networks(value);
  } else if (config.is_array()) {
    for (auto& value : config) value = smooth_networks(value);
  }
  return config;
}

/// A tiny "model" config of Ours' keys; `sh` empty leaves the SH bands to the method's default.
inline Json tiny_ours_model(const std::string& sh = "1") {
  const Json mlp = tiny_mlp(), freq = tiny_frequency();
  Json m = {{"renderer", {{"n_samples", 16}, {"n_dirs", 8}}},
            {"n_features", 4},
            {"density_grid", {{"resolution", 8}, {"march_steps", 16}}},
            {"property", {{"encoding", freq}, {"network", mlp}}},
            {"indirect", {{"light_encoding", freq}, {"network", mlp}}},
            {"visibility", {{"position_encoding", freq}, {"direction_encoding", freq}, {"network", mlp}}}};
  if (!sh.empty()) m["renderer"]["sh"] = sh;
  return m;
}

/// The settings of the method tests' tiny generated datasets: 12x12 images, one validation and one test view.
inline DatasetSettings tiny_dataset(std::uint32_t train, std::uint32_t spp, std::uint32_t seed = 3) {
  DatasetSettings s;
  s.resolution = 12;
  s.train = train;
  s.val = 1;
  s.test = 1;
  s.spp = spp;
  s.seed = seed;
  return s;
}

/// Sets an environment variable for the lifetime of the object, restoring the old value after.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::optional<std::string>& value) : m_name(name) {
    if (const char* old = std::getenv(name)) m_old = old;
    if (value)
      ::setenv(name, value->c_str(), 1);
    else
      ::unsetenv(name);
  }
  ~ScopedEnv() {
    if (m_old)
      ::setenv(m_name, m_old->c_str(), 1);
    else
      ::unsetenv(m_name);
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* m_name;
  std::optional<std::string> m_old;
};

/// One device description per kind of row of the kernel tables (relit/cl/kernel_variant.hpp): a CPU, NVIDIA,
/// AMD and Intel GPUs, and another accelerator.
struct TableDevices {
  DeviceInfo cpu, nvidia, amd, intel, other;
  TableDevices() {
    cpu.type = "cpu";
    cpu.vendor = "GenuineIntel";
    nvidia.type = amd.type = intel.type = "gpu";
    nvidia.vendor = "NVIDIA Corporation";
    amd.vendor = "Advanced Micro Devices, Inc.";
    intel.vendor = "Intel(R) Corporation";
    other.type = "accelerator";
    other.vendor = "Example";
  }
};

/// A fresh empty directory under the system temp dir, removed at destruction.
class TempDir {
 public:
  explicit TempDir(const std::string& tag) {
    m_path = std::filesystem::temp_directory_path() /
             ("relit-test-" + tag + "-" + std::to_string(::getpid()) + "-" + std::to_string(counter()++));
    std::filesystem::remove_all(m_path);
    std::filesystem::create_directories(m_path);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(m_path, ec);
  }
  const std::filesystem::path& path() const { return m_path; }

 private:
  static int& counter() {
    static int c = 0;
    return c;
  }
  std::filesystem::path m_path;
};

/// Every file under `dir` (recursively, hidden ones included) with its bytes: compare before and after an
/// operation to show that nothing was damaged, added or left behind.
inline std::map<std::string, std::string> snapshot(const std::filesystem::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : std::filesystem::recursive_directory_iterator(dir)) {
    const std::string rel = std::filesystem::relative(e.path(), dir).string();
    out[rel] = e.is_regular_file() ? io::read_file(e.path().string()) : std::string("<dir>");
  }
  return out;
}

/// Failure injection for the atomic writers while the object lives: every write whose target path
/// contains `target` fails at `stage` (after its temporary file exists) as a full disk or failed rename would.
class FailWrites {
 public:
  FailWrites(io::testing::Stage stage, std::string target = "") {
    io::testing::set_failure_hook([stage, target](io::testing::Stage s, const std::string& path) {
      if (s == stage && path.find(target) != std::string::npos) throw std::runtime_error("injected failure");
    });
  }
  ~FailWrites() { io::testing::set_failure_hook({}); }
  FailWrites(const FailWrites&) = delete;
  FailWrites& operator=(const FailWrites&) = delete;
};

}  // namespace relit::test
