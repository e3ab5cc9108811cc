// Device: one OpenCL device with its context, in-order queue and program cache.
//
// A Device is a cheap handle (copies share state). Selecting the same OpenCL device twice gives handles on
// the same context, so buffers and compiled programs are shared within a process.
//
// Selection (Device::select, and the RELIT_DEVICE environment variable, as pyopencl's PYOPENCL_CTX):
//   ""            RELIT_DEVICE if set, else the first GPU, else the first device
//   "1"           the device with global index 1 in list_devices() order
//   "0:1"         platform 0, its device 1; each side may also be a name fragment ("pocl:cpu")
//   "nvidia"      the first device whose platform, vendor, name or type contains the text (case-insensitive)
// Selection never asks interactively; it logs the chosen device at info level.
#pragma once

#include <CL/opencl.hpp>

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace relit {

/// What an OpenCL device is and can do, as reported by its driver.
struct DeviceInfo {
  int index = -1;           ///< global index across platforms (RELIT_DEVICE=<index>)
  int platform_index = -1;  ///< index of the platform
  int device_index = -1;    ///< index within the platform
  std::string platform_name, platform_vendor, platform_version;
  std::string name, vendor, type;  ///< type: "cpu", "gpu", "accelerator" or "other"
  std::string version, driver_version, opencl_c_version;
  unsigned compute_units = 0;
  unsigned max_clock_mhz = 0;
  std::uint64_t global_memory = 0;      ///< bytes
  std::uint64_t max_allocation = 0;     ///< largest single buffer, bytes
  std::uint64_t local_memory = 0;       ///< bytes per work-group
  bool local_memory_is_global = false;  ///< CPU drivers emulate local memory in RAM: no speed-up
  std::size_t max_work_group_size = 0;
  unsigned preferred_vector_width_float = 0;
  bool fp64 = false;
  std::vector<std::string> extensions;

  /// One line: "pthread-haswell-AMD EPYC [cpu, Portable Computing Language, 2 CUs, 4.4 GiB]".
  std::string description() const;
  bool has_extension(const std::string& name) const;
};

/// Smallest multiple of `multiple` that is >= value.
constexpr std::size_t round_up(std::size_t value, std::size_t multiple) {
  return multiple == 0 ? value : (value + multiple - 1) / multiple * multiple;
}

/// Every device of every OpenCL platform, in a stable order. Throws DeviceError when there is no OpenCL
/// platform at all, naming the driver package to install.
std::vector<DeviceInfo> list_devices();

/// -D definitions for a kernel build, e.g. {{"WIDTH", "64"}}. Ordered, so equal sets give equal options.
using Defines = std::map<std::string, std::string>;

class Program;
class Kernel;
namespace detail {
struct DeviceState;
}

class Device {
 public:
  /// Selects one device (see the file comment for the selector syntax). Throws DeviceError when nothing
  /// matches, listing the devices there are.
  static Device select(const std::string& selector = "");
  /// Every device the selector matches; "" or "all" gives every device.
  static std::vector<Device> select_all(const std::string& selector = "");

  Device() = default;
  bool valid() const { return m_state != nullptr; }

  const DeviceInfo& info() const;
  const cl::Device& cl_device() const;
  const cl::Context& context() const;
  /// The device's in-order command queue; all relit work on this device goes through it.
  const cl::CommandQueue& queue() const;
  /// Waits until everything enqueued on the queue has completed.
  void finish() const;

  /// Builds program `file` (a kernels/*.cl name such as "util.cl") with the given -D definitions and extra
  /// compiler options, or returns it from the in-process cache keyed by (device, source hash, options).
  /// Throws BuildError with the compiler's log on failure.
  Program program(const std::string& file, const Defines& defines = {}, const std::string& options = "") const;
  /// Shorthand for program(file, defines).kernel(name).
  Kernel kernel(const std::string& file, const std::string& name, const Defines& defines = {}) const;
  /// Number of programs in this device's in-process cache.
  std::size_t cached_programs() const;

  bool operator==(const Device& other) const { return m_state == other.m_state; }
  bool operator!=(const Device& other) const { return m_state != other.m_state; }

 private:
  explicit Device(std::shared_ptr<detail::DeviceState> state) : m_state(std::move(state)) {}
  const detail::DeviceState& state() const;
  std::shared_ptr<detail::DeviceState> m_state;
};

/// Adds a kernel source that Device::program() finds under `name` ("x.cl" or "x.clh"), like the files of
/// kernels/ that relit embeds: for a program's own kernels, such as the probe kernels of relit's tests and the
/// peers of its benchmarks, which are no part of the library. The text may #include relit's headers
/// ("common.clh"); RELIT_KERNEL_DIR still takes precedence. Adding a name again with the same text does
/// nothing; a name relit ships, or one already added with another text, throws InvalidArgument.
void add_kernel_source(const std::string& name, const std::string& text);

/// Outcome of building one program on a device (relit devices, the first test of the suite).
struct ProgramCheck {
  std::string file;
  bool ok = false;
  double seconds = 0.0;
  std::string error;  ///< the BuildError message when !ok
};

/// Builds every program in kernels/, and every one added with add_kernel_source(), on `device` with its
/// default definitions.
std::vector<ProgramCheck> check_programs(const Device& device);

}  // namespace relit
