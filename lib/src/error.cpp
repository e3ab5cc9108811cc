// Error messages, and the names of OpenCL status codes.
#include <relit/error.hpp>

#include <cstring>
#include <sstream>

namespace relit {

namespace {
// Keeps "lib/src/cl/device.cpp" of an absolute __FILE__, so messages do not carry build-machine paths.
const char* short_path(const char* file) {
  for (const char* marker : {"/lib/src/", "/lib/include/", "/apps/", "/bindings/", "/tests/", "/bench/"}) {
    if (const char* hit = std::strstr(file, marker)) return hit + 1;
  }
  return file;
}
}  // namespace

ConfigError::ConfigError(const std::string& pointer, const std::string& message)
    : InvalidArgument(pointer.empty() ? message : pointer + ": " + message), m_pointer(pointer), m_message(message) {}

ClError::ClError(int code, const std::string& call, const char* file, int line)
    : DeviceError([&] {
        std::ostringstream s;
        s << "OpenCL error " << cl_error_name(code) << " (" << code << ") in " << call << " at " << short_path(file)
          << ":" << line;
        if (code == -4 || code == -61) s << " (the device is out of memory: use a smaller batch or resolution)";
        if (code == -5) s << " (out of resources: often an out-of-bounds access in a kernel)";
        return s.str();
      }()),
      m_code(code),
      m_call(call) {}

BuildError::BuildError(const std::string& program, const std::string& device, const std::string& options,
                       const std::string& log, const std::string& source_path)
    : DeviceError("OpenCL program '" + program + "' failed to build on " + device +
                  "\n  options: " + (options.empty() ? "(none)" : options) + "\n  source saved to: " + source_path +
                  "\n  build log:\n" + log),
      m_program(program),
      m_device(device),
      m_options(options),
      m_log(log),
      m_source_path(source_path) {}

namespace detail {
void throw_cl_error(int code, const char* call, const char* file, int line) { throw ClError(code, call, file, line); }
}  // namespace detail

const char* cl_error_name(int code) {
  switch (code) {
    case 0: return "CL_SUCCESS";
    case -1: return "CL_DEVICE_NOT_FOUND";
    case -2: return "CL_DEVICE_NOT_AVAILABLE";
    case -3: return "CL_COMPILER_NOT_AVAILABLE";
    case -4: return "CL_MEM_OBJECT_ALLOCATION_FAILURE";
    case -5: return "CL_OUT_OF_RESOURCES";
    case -6: return "CL_OUT_OF_HOST_MEMORY";
    case -7: return "CL_PROFILING_INFO_NOT_AVAILABLE";
    case -8: return "CL_MEM_COPY_OVERLAP";
    case -9: return "CL_IMAGE_FORMAT_MISMATCH";
    case -10: return "CL_IMAGE_FORMAT_NOT_SUPPORTED";
    case -11: return "CL_BUILD_PROGRAM_FAILURE";
    case -12: return "CL_MAP_FAILURE";
    case -13: return "CL_MISALIGNED_SUB_BUFFER_OFFSET";
    case -14: return "CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST";
    case -15: return "CL_COMPILE_PROGRAM_FAILURE";
    case -16: return "CL_LINKER_NOT_AVAILABLE";
    case -17: return "CL_LINK_PROGRAM_FAILURE";
    case -18: return "CL_DEVICE_PARTITION_FAILED";
    case -19: return "CL_KERNEL_ARG_INFO_NOT_AVAILABLE";
    case -30: return "CL_INVALID_VALUE";
    case -31: return "CL_INVALID_DEVICE_TYPE";
    case -32: return "CL_INVALID_PLATFORM";
    case -33: return "CL_INVALID_DEVICE";
    case -34: return "CL_INVALID_CONTEXT";
    case -35: return "CL_INVALID_QUEUE_PROPERTIES";
    case -36: return "CL_INVALID_COMMAND_QUEUE";
    case -37: return "CL_INVALID_HOST_PTR";
    case -38: return "CL_INVALID_MEM_OBJECT";
    case -39: return "CL_INVALID_IMAGE_FORMAT_DESCRIPTOR";
    case -40: return "CL_INVALID_IMAGE_SIZE";
    case -41: return "CL_INVALID_SAMPLER";
    case -42: return "CL_INVALID_BINARY";
    case -43: return "CL_INVALID_BUILD_OPTIONS";
    case -44: return "CL_INVALID_PROGRAM";
    case -45: return "CL_INVALID_PROGRAM_EXECUTABLE";
    case -46: return "CL_INVALID_KERNEL_NAME";
    case -47: return "CL_INVALID_KERNEL_DEFINITION";
    case -48: return "CL_INVALID_KERNEL";
    case -49: return "CL_INVALID_ARG_INDEX";
    case -50: return "CL_INVALID_ARG_VALUE";
    case -51: return "CL_INVALID_ARG_SIZE";
    case -52: return "CL_INVALID_KERNEL_ARGS";
    case -53: return "CL_INVALID_WORK_DIMENSION";
    case -54: return "CL_INVALID_WORK_GROUP_SIZE";
    case -55: return "CL_INVALID_WORK_ITEM_SIZE";
    case -56: return "CL_INVALID_GLOBAL_OFFSET";
    case -57: return "CL_INVALID_EVENT_WAIT_LIST";
    case -58: return "CL_INVALID_EVENT";
    case -59: return "CL_INVALID_OPERATION";
    case -60: return "CL_INVALID_GL_OBJECT";
    case -61: return "CL_INVALID_BUFFER_SIZE";
    case -62: return "CL_INVALID_MIP_LEVEL";
    case -63: return "CL_INVALID_GLOBAL_WORK_SIZE";
    case -64: return "CL_INVALID_PROPERTY";
    case -65: return "CL_INVALID_IMAGE_DESCRIPTOR";
    case -66: return "CL_INVALID_COMPILER_OPTIONS";
    case -67: return "CL_INVALID_LINKER_OPTIONS";
    case -68: return "CL_INVALID_DEVICE_PARTITION_COUNT";
    case -1001: return "CL_PLATFORM_NOT_FOUND_KHR";
    default: return "CL_UNKNOWN_ERROR";
  }
}

}  // namespace relit
