// Building programs (with the in-process cache) and launching kernels.
#include "cl/device_state.hpp"
#include "cl/kernel_sources.hpp"

#include <relit/cl/program.hpp>
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/log.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace relit {

namespace {

std::string build_options(const Defines& defines, const std::string& extra) {
  std::string options = "-cl-std=CL1.2";
  for (const auto& [name, value] : defines) {
    if (name.empty() || name.find_first_of(" \t=\"'") != std::string::npos)
      throw InvalidArgument("kernel define '" + name + "' is not a valid macro name");
    options += " -D" + name;
    if (!value.empty()) options += "=" + value;
  }
  if (!extra.empty()) options += " " + extra;
  return options;
}

// Writes the failing source where a person can open it; the compiler's line numbers refer to it.
std::string save_failed_source(const std::string& file, std::uint64_t hash, const std::string& source) {
  std::error_code ec;
  const auto dir = std::filesystem::temp_directory_path(ec) / "relit-build-errors";
  std::filesystem::create_directories(dir, ec);
  char name[32];
  std::snprintf(name, sizeof name, "%016llx", static_cast<unsigned long long>(hash));
  const auto path = dir / (std::filesystem::path(file).stem().string() + "-" + name + ".cl");
  try {
    io::write_file_atomic(path.string(), source);
  } catch (const Error&) {
    return "(could not be saved: " + path.string() + " is not writable)";
  }
  return path.string();
}

}  // namespace

Program Device::program(const std::string& file, const Defines& defines, const std::string& extra_options) const {
  auto& s = const_cast<detail::DeviceState&>(state());
  const std::string source = detail::resolve_kernel_source(file);
  const std::string options = build_options(defines, extra_options);
  const auto key = std::make_pair(detail::fnv1a(source), options);
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    if (auto it = s.programs.find(key); it != s.programs.end()) return Program(*this, it->second, file, options);
  }
  const auto t0 = std::chrono::steady_clock::now();
  cl_int status = CL_SUCCESS;
  cl::Program program(s.context, source, false, &status);
  RELIT_CL_CHECK_CODE(status, "clCreateProgramWithSource");
  status = program.build(std::vector<cl::Device>{s.device}, options.c_str());
  if (status == CL_BUILD_PROGRAM_FAILURE || status == CL_INVALID_BUILD_OPTIONS ||
      status == CL_COMPILE_PROGRAM_FAILURE) {
    std::string log;
    program.getBuildInfo(s.device, CL_PROGRAM_BUILD_LOG, &log);
    if (status == CL_INVALID_BUILD_OPTIONS) log = "invalid build options\n" + log;
    throw BuildError(file, s.info.description(), options, log, save_failed_source(file, key.first, source));
  }
  RELIT_CL_CHECK_CODE(status, "clBuildProgram");
  log_debug("built " + file + " (" + options + ") in " +
            std::to_string(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()) + " s");
  std::lock_guard<std::mutex> lock(s.mutex);
  s.programs.emplace(key, program);
  return Program(*this, program, file, options);
}

Kernel Program::kernel(const std::string& name) const {
  cl_int status = CL_SUCCESS;
  cl::Kernel kernel(m_program, name.c_str(), &status);
  if (status == CL_INVALID_KERNEL_NAME) {
    std::string names;
    for (const auto& n : kernel_names()) names += " " + n;
    throw InvalidArgument("program " + m_file + " has no kernel '" + name + "'; it has:" + names);
  }
  RELIT_CL_CHECK_CODE(status, ("clCreateKernel(" + name + ")").c_str());
  return Kernel(m_device, kernel, name);
}

std::vector<std::string> Program::kernel_names() const {
  std::string names;
  RELIT_CL_CHECK(m_program.getInfo(CL_PROGRAM_KERNEL_NAMES, &names));
  std::vector<std::string> out;
  std::stringstream s(names);
  for (std::string n; std::getline(s, n, ';');)
    if (!n.empty()) out.push_back(n);
  return out;
}

void Kernel::check(cl_int status, unsigned index) const {
  if (status != CL_SUCCESS)
    detail::throw_cl_error(status, ("clSetKernelArg(" + m_name + ", arg " + std::to_string(index) + ")").c_str(),
                           __FILE__, __LINE__);
}

void Kernel::launch(std::size_t global_size, std::size_t local_size) const {
  if (global_size == 0) return;
  const cl::NDRange local = local_size ? cl::NDRange(local_size) : cl::NullRange;
  launch(cl::NDRange(round_up(global_size, local_size)), local);
}

void Kernel::launch(const cl::NDRange& global, const cl::NDRange& local) const {
  const cl_int status = m_device.queue().enqueueNDRangeKernel(m_kernel, cl::NullRange, global, local);
  if (status != CL_SUCCESS)
    detail::throw_cl_error(status, ("clEnqueueNDRangeKernel(" + m_name + ")").c_str(), __FILE__, __LINE__);
}

std::size_t Kernel::max_work_group_size() const {
  std::size_t v = 0;
  RELIT_CL_CHECK(m_kernel.getWorkGroupInfo(m_device.cl_device(), CL_KERNEL_WORK_GROUP_SIZE, &v));
  return v;
}

std::size_t Kernel::preferred_work_group_multiple() const {
  std::size_t v = 0;
  RELIT_CL_CHECK(m_kernel.getWorkGroupInfo(m_device.cl_device(), CL_KERNEL_PREFERRED_WORK_GROUP_SIZE_MULTIPLE, &v));
  return v;
}

}  // namespace relit
