// Program and Kernel: compiled OpenCL code and launchable kernels with checked arguments.
//
//   relit::Kernel k = device.kernel("util.cl", "axpy_f32");
//   k.args(n, 2.0f, x, y).launch(n);                   // 1-D, n work-items, driver-chosen local size
//
// launch(n, local) rounds the global size up to a multiple of `local` (some drivers, PoCL among them,
// need uniform work-groups), so kernels take the true item count and return early past it.
#pragma once

#include <relit/cl/buffer.hpp>
#include <relit/cl/device.hpp>

#include <CL/opencl.hpp>

#include <string>
#include <vector>

namespace relit {

class Program {
 public:
  Program() = default;
  Program(Device device, cl::Program program, std::string file, std::string options)
      : m_device(std::move(device)),
        m_program(std::move(program)),
        m_file(std::move(file)),
        m_options(std::move(options)) {}

  Kernel kernel(const std::string& name) const;
  std::vector<std::string> kernel_names() const;
  const std::string& file() const { return m_file; }
  const std::string& options() const { return m_options; }
  const cl::Program& handle() const { return m_program; }

 private:
  Device m_device;
  cl::Program m_program;
  std::string m_file, m_options;
};

class Kernel {
 public:
  Kernel() = default;
  Kernel(Device device, cl::Kernel kernel, std::string name)
      : m_device(std::move(device)), m_kernel(std::move(kernel)), m_name(std::move(name)) {}

  /// Sets argument `index` to a scalar or vector value (int, float, cl_float4, ...).
  template <class T>
  Kernel& arg(unsigned index, const T& value) {
    check(m_kernel.setArg(index, sizeof(T), &value), index);
    return *this;
  }
  /// Sets argument `index` to a device buffer (an empty buffer passes NULL).
  template <class T>
  Kernel& arg(unsigned index, const Buffer<T>& buffer) {
    cl_mem mem = buffer.empty() ? nullptr : buffer.handle()();
    check(m_kernel.setArg(index, sizeof(cl_mem), &mem), index);
    return *this;
  }
  template <class T>
  Kernel& arg(unsigned index, Buffer<T>& buffer) {
    return arg(index, static_cast<const Buffer<T>&>(buffer));
  }
  /// Sets arguments 0, 1, ... in order.
  template <class... Args>
  Kernel& args(Args&&... values) {
    unsigned index = 0;
    (arg(index++, values), ...);
    return *this;
  }

  /// Enqueues `global_size` work-items (rounded up to a multiple of `local_size` when that is non-zero).
  /// Asynchronous: returns before the kernel has run.
  void launch(std::size_t global_size, std::size_t local_size = 0) const;
  /// 2-D and 3-D launches; sizes must be multiples of the local sizes (use round_up).
  void launch(const cl::NDRange& global, const cl::NDRange& local) const;

  const std::string& name() const { return m_name; }
  const cl::Kernel& handle() const { return m_kernel; }
  /// CL_KERNEL_WORK_GROUP_SIZE for this kernel on its device.
  std::size_t max_work_group_size() const;
  /// CL_KERNEL_PREFERRED_WORK_GROUP_SIZE_MULTIPLE (warp / wavefront / SIMD width).
  std::size_t preferred_work_group_multiple() const;

 private:
  void check(cl_int status, unsigned index) const;
  Device m_device;
  cl::Kernel m_kernel;
  std::string m_name;
};

}  // namespace relit
