// The exceptions relit throws. Every message names what went wrong, where, and what to do about it.
//
//   Error                      base of everything relit throws
//   ├── InvalidArgument        bad parameter or config value          (Python: ValueError)
//   │   └── ConfigError        bad JSON config: carries the JSON pointer
//   ├── IOError                missing, unreadable or corrupt file     (Python: OSError)
//   ├── ParallelError          another MPI rank failed or did not answer (Python: RuntimeError)
//   └── DeviceError            OpenCL device problems                  (Python: RuntimeError)
//       ├── ClError            an OpenCL call failed: call, code name, file:line
//       └── BuildError         a kernel failed to compile: device, options, full log, saved source
#pragma once

#include <stdexcept>
#include <string>

namespace relit {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& message) : std::runtime_error(message) {}
};

class InvalidArgument : public Error {
 public:
  using Error::Error;
};

class ConfigError : public InvalidArgument {
 public:
  /// `pointer` is the JSON pointer of the offending value ("/network/n_neurons"), "" for the document.
  ConfigError(const std::string& pointer, const std::string& message);
  const std::string& pointer() const { return m_pointer; }
  /// The message without the pointer in front (what() is "pointer: message").
  const std::string& message() const { return m_message; }

 private:
  std::string m_pointer, m_message;
};

class IOError : public Error {
 public:
  using Error::Error;
};

class ParallelError : public Error {
 public:
  using Error::Error;
};

class DeviceError : public Error {
 public:
  using Error::Error;
};

class ClError : public DeviceError {
 public:
  ClError(int code, const std::string& call, const char* file, int line);
  int code() const { return m_code; }
  const std::string& call() const { return m_call; }

 private:
  int m_code;
  std::string m_call;
};

class BuildError : public DeviceError {
 public:
  BuildError(const std::string& program, const std::string& device, const std::string& options, const std::string& log,
             const std::string& source_path);
  const std::string& program() const { return m_program; }
  const std::string& device() const { return m_device; }
  const std::string& options() const { return m_options; }
  const std::string& log() const { return m_log; }
  /// Where the complete, include-resolved source that failed was written, for the compiler's line numbers.
  const std::string& source_path() const { return m_source_path; }

 private:
  std::string m_program, m_device, m_options, m_log, m_source_path;
};

/// The OpenCL name of an error code: -5 → "CL_OUT_OF_RESOURCES".
const char* cl_error_name(int code);

namespace detail {
[[noreturn]] void throw_cl_error(int code, const char* call, const char* file, int line);
}  // namespace detail

}  // namespace relit

/// Checks the cl_int status of an OpenCL call and throws relit::ClError naming the call on failure:
///   RELIT_CL_CHECK(clFinish(queue));     or    RELIT_CL_CHECK_CODE(err, "clCreateBuffer");
#define RELIT_CL_CHECK(call)                                                                                 \
  do {                                                                                                       \
    const int relit_cl_status_ = static_cast<int>(call);                                                     \
    if (relit_cl_status_ != 0) ::relit::detail::throw_cl_error(relit_cl_status_, #call, __FILE__, __LINE__); \
  } while (0)
#define RELIT_CL_CHECK_CODE(status, name)                                                                   \
  do {                                                                                                      \
    const int relit_cl_status_ = static_cast<int>(status);                                                  \
    if (relit_cl_status_ != 0) ::relit::detail::throw_cl_error(relit_cl_status_, name, __FILE__, __LINE__); \
  } while (0)
