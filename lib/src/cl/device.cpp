// Device enumeration and selection.
#include "cl/device_state.hpp"
#include "cl/kernel_sources.hpp"
#include "shared.hpp"

#include <relit/cl/buffer.hpp>
#include <relit/cl/program.hpp>
#include <relit/error.hpp>
#include <relit/log.hpp>
#include <relit/parallel.hpp>

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <cctype>
#include <chrono>
#include <cstdlib>
#include <iomanip>
#include <sstream>

namespace relit {

namespace {

using ::relit::detail::lower;

constexpr cl_int kPlatformNotFound = -1001;  // CL_PLATFORM_NOT_FOUND_KHR, returned by ICD loaders

const char* const kNoPlatformHelp =
    "no OpenCL platform found. Install an OpenCL driver: on Debian/Ubuntu `apt-get install pocl-opencl-icd` "
    "(CPU), or your GPU vendor's OpenCL driver. Drivers register in /etc/OpenCL/vendors (or OCL_ICD_VENDORS); "
    "`clinfo -l` lists what the loader sees.";

std::string trim(std::string s) {
  while (!s.empty() && (std::isspace(static_cast<unsigned char>(s.back())) || s.back() == '\0')) s.pop_back();
  std::size_t b = 0;
  while (b < s.size() && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  return s.substr(b);
}

bool is_index(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](unsigned char c) { return std::isdigit(c); });
}

// The value of an index selector; one too large for any machine (99999999999999999999) matches nothing.
long long index_value(const std::string& s) { return s.size() > 9 ? -1 : std::stoll(s); }

template <cl_device_info Name, class T>
T device_query(const cl::Device& d, const char* what) {
  T value{};
  RELIT_CL_CHECK_CODE(d.getInfo(Name, &value), what);
  return value;
}

std::string device_string(const cl::Device& d, cl_device_info name, const char* what) {
  std::string value;
  RELIT_CL_CHECK_CODE(d.getInfo(name, &value), what);
  return trim(value);
}

std::string platform_string(const cl::Platform& p, cl_platform_info name, const char* what) {
  std::string value;
  RELIT_CL_CHECK_CODE(p.getInfo(name, &value), what);
  return trim(value);
}

struct Enumerated {
  DeviceInfo info;
  cl::Device device;
};

// PoCL refuses to start when its kernel cache folder cannot be written, and the ICD loader then reports no
// platform at all: name the real cause instead of asking for a driver that is installed.
std::string no_platform_message() {
  for (const char* var : {"POCL_CACHE_DIR", "XDG_CACHE_HOME"}) {
    const char* dir = std::getenv(var);
    if (!dir || !*dir) continue;
    std::error_code ec;
    const bool exists = std::filesystem::exists(dir, ec);
    if (!exists || !std::filesystem::is_directory(dir, ec) || ::access(dir, W_OK | X_OK) != 0)
      return std::string("no OpenCL platform could start: ") + var + "='" + dir + "' " +
             (exists ? "is not a writable folder" : "does not exist") +
             ", and the PoCL driver needs it for its kernel cache. Point " + var +
             " at a writable folder (or unset it). If that is not the cause: " + kNoPlatformHelp;
  }
  return kNoPlatformHelp;
}

std::vector<Enumerated> enumerate() {
  std::vector<cl::Platform> platforms;
  const cl_int status = cl::Platform::get(&platforms);
  if (status == kPlatformNotFound || (status == CL_SUCCESS && platforms.empty()))
    throw DeviceError(no_platform_message());
  RELIT_CL_CHECK_CODE(status, "clGetPlatformIDs");

  std::vector<Enumerated> out;
  for (std::size_t p = 0; p < platforms.size(); ++p) {
    std::vector<cl::Device> devices;
    const cl_int s = platforms[p].getDevices(CL_DEVICE_TYPE_ALL, &devices);
    if (s == CL_DEVICE_NOT_FOUND) continue;
    RELIT_CL_CHECK_CODE(s, "clGetDeviceIDs");
    for (std::size_t d = 0; d < devices.size(); ++d) {
      const cl::Device& dev = devices[d];
      DeviceInfo info;
      info.index = static_cast<int>(out.size());
      info.platform_index = static_cast<int>(p);
      info.device_index = static_cast<int>(d);
      info.platform_name = platform_string(platforms[p], CL_PLATFORM_NAME, "clGetPlatformInfo(CL_PLATFORM_NAME)");
      info.platform_vendor = platform_string(platforms[p], CL_PLATFORM_VENDOR, "clGetPlatformInfo(CL_PLATFORM_VENDOR)");
      info.platform_version =
          platform_string(platforms[p], CL_PLATFORM_VERSION, "clGetPlatformInfo(CL_PLATFORM_VERSION)");
      info.name = device_string(dev, CL_DEVICE_NAME, "clGetDeviceInfo(CL_DEVICE_NAME)");
      info.vendor = device_string(dev, CL_DEVICE_VENDOR, "clGetDeviceInfo(CL_DEVICE_VENDOR)");
      info.version = device_string(dev, CL_DEVICE_VERSION, "clGetDeviceInfo(CL_DEVICE_VERSION)");
      info.driver_version = device_string(dev, CL_DRIVER_VERSION, "clGetDeviceInfo(CL_DRIVER_VERSION)");
      info.opencl_c_version =
          device_string(dev, CL_DEVICE_OPENCL_C_VERSION, "clGetDeviceInfo(CL_DEVICE_OPENCL_C_VERSION)");
      const auto type = device_query<CL_DEVICE_TYPE, cl_device_type>(dev, "clGetDeviceInfo(CL_DEVICE_TYPE)");
      info.type = (type & CL_DEVICE_TYPE_GPU)           ? "gpu"
                  : (type & CL_DEVICE_TYPE_CPU)         ? "cpu"
                  : (type & CL_DEVICE_TYPE_ACCELERATOR) ? "accelerator"
                                                        : "other";
      info.compute_units =
          device_query<CL_DEVICE_MAX_COMPUTE_UNITS, cl_uint>(dev, "clGetDeviceInfo(CL_DEVICE_MAX_COMPUTE_UNITS)");
      info.max_clock_mhz =
          device_query<CL_DEVICE_MAX_CLOCK_FREQUENCY, cl_uint>(dev, "clGetDeviceInfo(CL_DEVICE_MAX_CLOCK_FREQUENCY)");
      info.global_memory =
          device_query<CL_DEVICE_GLOBAL_MEM_SIZE, cl_ulong>(dev, "clGetDeviceInfo(CL_DEVICE_GLOBAL_MEM_SIZE)");
      info.max_allocation =
          device_query<CL_DEVICE_MAX_MEM_ALLOC_SIZE, cl_ulong>(dev, "clGetDeviceInfo(CL_DEVICE_MAX_MEM_ALLOC_SIZE)");
      info.local_memory =
          device_query<CL_DEVICE_LOCAL_MEM_SIZE, cl_ulong>(dev, "clGetDeviceInfo(CL_DEVICE_LOCAL_MEM_SIZE)");
      info.local_memory_is_global = device_query<CL_DEVICE_LOCAL_MEM_TYPE, cl_device_local_mem_type>(
                                        dev, "clGetDeviceInfo(CL_DEVICE_LOCAL_MEM_TYPE)") == CL_GLOBAL;
      info.max_work_group_size =
          device_query<CL_DEVICE_MAX_WORK_GROUP_SIZE, size_t>(dev, "clGetDeviceInfo(CL_DEVICE_MAX_WORK_GROUP_SIZE)");
      info.preferred_vector_width_float = device_query<CL_DEVICE_PREFERRED_VECTOR_WIDTH_FLOAT, cl_uint>(
          dev, "clGetDeviceInfo(CL_DEVICE_PREFERRED_VECTOR_WIDTH_FLOAT)");
      std::istringstream ext(device_string(dev, CL_DEVICE_EXTENSIONS, "clGetDeviceInfo(CL_DEVICE_EXTENSIONS)"));
      for (std::string e; ext >> e;) info.extensions.push_back(e);
      std::sort(info.extensions.begin(), info.extensions.end());
      info.fp64 = info.has_extension("cl_khr_fp64") || device_query<CL_DEVICE_DOUBLE_FP_CONFIG, cl_device_fp_config>(
                                                           dev, "clGetDeviceInfo(CL_DEVICE_DOUBLE_FP_CONFIG)") != 0;
      out.push_back({std::move(info), dev});
    }
  }
  if (out.empty())
    throw DeviceError("OpenCL platforms were found but they have no devices. " + std::string(kNoPlatformHelp));
  return out;
}

// The text a name fragment is matched against.
std::string platform_haystack(const DeviceInfo& i) {
  return lower(i.platform_name + " " + i.platform_vendor + " " + i.platform_version);
}
std::string device_haystack(const DeviceInfo& i) { return lower(i.name + " " + i.vendor + " " + i.type); }

bool matches_part(const std::string& part, int index, const std::string& haystack) {
  if (part.empty()) return true;
  if (is_index(part)) return index_value(part) == index;
  return haystack.find(lower(part)) != std::string::npos;
}

bool matches(const std::string& selector, const DeviceInfo& info) {
  const std::string s = trim(selector);
  if (s.empty() || lower(s) == "all") return true;
  if (is_index(s)) return index_value(s) == info.index;
  if (const auto colon = s.find(':'); colon != std::string::npos) {
    return matches_part(trim(s.substr(0, colon)), info.platform_index, platform_haystack(info)) &&
           matches_part(trim(s.substr(colon + 1)), info.device_index, device_haystack(info));
  }
  return (platform_haystack(info) + " " + device_haystack(info)).find(lower(s)) != std::string::npos;
}

std::string available_list(const std::vector<Enumerated>& all) {
  std::string s;
  for (const auto& e : all)
    s += "\n  " + std::to_string(e.info.index) + " (" + std::to_string(e.info.platform_index) + ":" +
         std::to_string(e.info.device_index) + "): " + e.info.description();
  return s;
}

std::string no_match_message(const std::string& selector, const std::string& source,
                             const std::vector<Enumerated>& all) {
  const std::string what =
      source == "RELIT_DEVICE" ? "RELIT_DEVICE='" + selector + "'" : "device selector '" + selector + "'";
  return what +
         " matches no OpenCL device. Use an index, 'platform:device' (indices or name parts), or a part of "
         "a platform or device name (case-insensitive). Devices:" +
         available_list(all);
}

// Handles on one cl_device_id share one state, so buffers and cached programs are shared in a process.
std::shared_ptr<detail::DeviceState> open_state(const Enumerated& e) {
  static std::mutex mutex;
  static std::map<cl_device_id, std::weak_ptr<detail::DeviceState>> open;
  std::lock_guard<std::mutex> lock(mutex);
  if (auto existing = open[e.device()].lock()) return existing;
  auto state = std::make_shared<detail::DeviceState>();
  state->info = e.info;
  state->device = e.device;
  cl_int status = CL_SUCCESS;
  state->context = cl::Context(e.device, nullptr, nullptr, nullptr, &status);
  RELIT_CL_CHECK_CODE(status, "clCreateContext");
  state->queue = cl::CommandQueue(state->context, e.device, 0, &status);
  RELIT_CL_CHECK_CODE(status, "clCreateCommandQueue");
  open[e.device()] = state;
  return state;
}

std::string selector_or_env(const std::string& selector, std::string& source) {
  if (!trim(selector).empty()) {
    source = "selector";
    return selector;
  }
  if (const char* env = std::getenv("RELIT_DEVICE"); env && *env) {
    source = "RELIT_DEVICE";
    return env;
  }
  source = "default";
  return "";
}

}  // namespace

std::string DeviceInfo::description() const {
  std::ostringstream s;
  s << name << " [" << type << ", " << platform_name << ", " << compute_units << " CUs, " << std::fixed
    << std::setprecision(1) << global_memory / (1024.0 * 1024.0 * 1024.0) << " GiB]";
  return s.str();
}

bool DeviceInfo::has_extension(const std::string& ext) const {
  return std::binary_search(extensions.begin(), extensions.end(), ext);
}

std::vector<DeviceInfo> list_devices() {
  std::vector<DeviceInfo> out;
  for (auto& e : enumerate()) out.push_back(std::move(e.info));
  return out;
}

Device Device::select(const std::string& selector) {
  std::string source;
  const std::string s = selector_or_env(selector, source);
  const auto all = enumerate();
  const Enumerated* chosen = nullptr;
  // Several ranks on this machine (MPI): by default rank r of the machine takes its r-th GPU (or device, when
  // there is no GPU), sharing them round-robin when there are fewer; "distinct" refuses to share.
  const int local_ranks = parallel::local_size(), local_rank = parallel::local_rank();
  const bool distinct = lower(trim(s)) == "distinct";
  if (source == "default" || distinct) {
    std::vector<const Enumerated*> pool;
    for (const auto& e : all)
      if (e.info.type == "gpu") pool.push_back(&e);
    if (pool.empty())
      for (const auto& e : all) pool.push_back(&e);
    if (distinct && local_ranks > int(pool.size()))
      throw DeviceError(std::string(source == "RELIT_DEVICE" ? "RELIT_DEVICE" : "the device selector") +
                        " 'distinct' asks for one device per rank, but " + std::to_string(local_ranks) +
                        " ranks run on this machine and it has " + std::to_string(pool.size()) + " " +
                        (pool.front()->info.type == "gpu" ? "GPU" : "device") + (pool.size() == 1 ? "" : "s") +
                        ": start at most that many ranks per machine, or let ranks share devices (no selector)."
                        " Devices:" +
                        available_list(all));
    chosen = pool[std::size_t(local_rank) % pool.size()];
    if (local_ranks > int(pool.size()) && local_rank < local_ranks)
      log_info(parallel::rank_prefix() + std::to_string(local_ranks) + " ranks on this machine share " +
               std::to_string(pool.size()) + " device(s)");
  } else {
    for (const auto& e : all)
      if (matches(s, e.info)) {
        chosen = &e;
        break;
      }
  }
  if (!chosen) throw DeviceError(no_match_message(s, source, all));
  Device device(open_state(*chosen));
  log_info(parallel::rank_prefix() + "device " + std::to_string(chosen->info.index) + ": " +
           chosen->info.description() + (source == "default" ? "" : " (" + source + " '" + trim(s) + "')"));
  return device;
}

std::vector<Device> Device::select_all(const std::string& selector) {
  std::string source;
  const std::string s = selector_or_env(selector, source);
  const auto all = enumerate();
  std::vector<Device> out;
  for (const auto& e : all)
    if (matches(s, e.info)) out.push_back(Device(open_state(e)));
  if (out.empty()) throw DeviceError(no_match_message(s, source, all));
  return out;
}

const detail::DeviceState& Device::state() const {
  if (!m_state) throw InvalidArgument("use of an empty relit::Device; create one with Device::select()");
  return *m_state;
}

const DeviceInfo& Device::info() const { return state().info; }
const cl::Device& Device::cl_device() const { return state().device; }
const cl::Context& Device::context() const { return state().context; }
const cl::CommandQueue& Device::queue() const { return state().queue; }
void Device::finish() const { RELIT_CL_CHECK(state().queue.finish()); }

std::size_t Device::cached_programs() const {
  std::lock_guard<std::mutex> lock(m_state->mutex);
  return m_state->programs.size();
}

Kernel Device::kernel(const std::string& file, const std::string& name, const Defines& defines) const {
  return program(file, defines).kernel(name);
}

std::vector<ProgramCheck> check_programs(const Device& device) {
  std::vector<ProgramCheck> out;
  for (const auto& file : detail::program_files()) {
    ProgramCheck check;
    check.file = file;
    const auto t0 = std::chrono::steady_clock::now();
    try {
      device.program(file);
      check.ok = true;
    } catch (const Error& e) {
      check.error = e.what();
    }
    check.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    out.push_back(std::move(check));
  }
  return out;
}

namespace detail {

cl::Buffer create_buffer(const Device& device, std::size_t bytes, cl_mem_flags flags) {
  const auto& info = device.info();
  if (bytes > info.max_allocation) {
    std::ostringstream s;
    s << "cannot allocate a buffer of " << bytes << " bytes on " << info.name << ": its largest allocation is "
      << info.max_allocation << " bytes; use smaller batches or tiles";
    throw InvalidArgument(s.str());
  }
  cl_int status = CL_SUCCESS;
  cl::Buffer buffer(device.context(), flags, bytes, nullptr, &status);
  RELIT_CL_CHECK_CODE(status, "clCreateBuffer");
  return buffer;
}

void throw_buffer_range(const char* what, const char* type, std::size_t offset, std::size_t count, std::size_t size) {
  std::ostringstream s;
  s << "Buffer<" << type << ">::" << what << ": elements [" << offset << ", " << offset + count
    << ") are outside the buffer of " << size << " elements";
  throw InvalidArgument(s.str());
}

}  // namespace detail

}  // namespace relit
