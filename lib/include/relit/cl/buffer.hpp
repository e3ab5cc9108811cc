// Buffer<T>: a typed, RAII-owned device buffer whose copies are checked against its size.
//
//   relit::Buffer<float> x(device, 1024);      // uninitialised
//   x.write(host_vector);                      // throws InvalidArgument if it does not fit
//   std::vector<float> back = x.read();        // blocking read of the whole buffer
//
// Copies between host and device are blocking unless stated; kernel launches are not, and the in-order
// queue keeps them in sequence.
#pragma once

#include <relit/cl/device.hpp>
#include <relit/error.hpp>

#include <CL/opencl.hpp>

#include <string>
#include <type_traits>
#include <vector>

namespace relit {

namespace detail {
[[noreturn]] void throw_buffer_range(const char* what, const char* type, std::size_t offset, std::size_t count,
                                     std::size_t size);
cl::Buffer create_buffer(const Device& device, std::size_t bytes, cl_mem_flags flags);

template <class T>
constexpr const char* element_name() {
  if constexpr (std::is_same_v<T, float>)
    return "float";
  else if constexpr (std::is_same_v<T, double>)
    return "double";
  else if constexpr (std::is_same_v<T, int>)
    return "int";
  else if constexpr (std::is_same_v<T, unsigned>)
    return "uint";
  else if constexpr (std::is_same_v<T, unsigned char>)
    return "uchar";
  else
    return "element";
}
}  // namespace detail

template <class T>
class Buffer {
  static_assert(std::is_trivially_copyable_v<T>, "Buffer<T> holds plain data only");

 public:
  Buffer() = default;
  /// `count` elements of uninitialised device memory.
  Buffer(const Device& device, std::size_t count, cl_mem_flags flags = CL_MEM_READ_WRITE)
      : m_device(device), m_count(count) {
    if (count) m_buffer = detail::create_buffer(device, count * sizeof(T), flags);
  }
  /// A device copy of `host`.
  Buffer(const Device& device, const std::vector<T>& host, cl_mem_flags flags = CL_MEM_READ_WRITE)
      : Buffer(device, host.size(), flags) {
    write(host);
  }

  std::size_t size() const { return m_count; }
  std::size_t bytes() const { return m_count * sizeof(T); }
  bool empty() const { return m_count == 0; }
  const Device& device() const { return m_device; }
  const cl::Buffer& handle() const { return m_buffer; }

  /// Copies `count` elements from `data` into the buffer at element `offset`.
  void write(const T* data, std::size_t count, std::size_t offset = 0) {
    check_range("write", offset, count);
    if (count)
      RELIT_CL_CHECK(
          m_device.queue().enqueueWriteBuffer(m_buffer, CL_TRUE, offset * sizeof(T), count * sizeof(T), data));
  }
  void write(const std::vector<T>& data, std::size_t offset = 0) { write(data.data(), data.size(), offset); }

  /// Copies `count` elements starting at element `offset` into `out`.
  void read(T* out, std::size_t count, std::size_t offset = 0) const {
    check_range("read", offset, count);
    if (count)
      RELIT_CL_CHECK(m_device.queue().enqueueReadBuffer(m_buffer, CL_TRUE, offset * sizeof(T), count * sizeof(T), out));
  }
  std::vector<T> read() const {
    std::vector<T> out(m_count);
    read(out.data(), m_count);
    return out;
  }

  /// Sets `count` elements from `offset` (default: all) to `value`, asynchronously.
  void fill(const T& value, std::size_t offset = 0, std::size_t count = npos) {
    if (count == npos) count = offset <= m_count ? m_count - offset : 0;
    check_range("fill", offset, count);
    if (count)
      RELIT_CL_CHECK(m_device.queue().enqueueFillBuffer(m_buffer, value, offset * sizeof(T), count * sizeof(T)));
  }

  /// Copies `count` elements of `src` (from `src_offset`) to this buffer at `dst_offset`, asynchronously.
  void copy_from(const Buffer<T>& src, std::size_t count, std::size_t src_offset = 0, std::size_t dst_offset = 0) {
    src.check_range("copy_from (source)", src_offset, count);
    check_range("copy_from (destination)", dst_offset, count);
    if (count)
      RELIT_CL_CHECK(m_device.queue().enqueueCopyBuffer(src.m_buffer, m_buffer, src_offset * sizeof(T),
                                                        dst_offset * sizeof(T), count * sizeof(T)));
  }

  static constexpr std::size_t npos = static_cast<std::size_t>(-1);

 private:
  void check_range(const char* what, std::size_t offset, std::size_t count) const {
    if (offset > m_count || count > m_count - offset)
      detail::throw_buffer_range(what, detail::element_name<T>(), offset, count, m_count);
  }

  Device m_device;
  cl::Buffer m_buffer;
  std::size_t m_count = 0;
};

}  // namespace relit
