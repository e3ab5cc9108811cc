// The shared state behind relit::Device handles.
#pragma once

#include <relit/cl/device.hpp>

#include <map>
#include <mutex>
#include <string>
#include <utility>

namespace relit::detail {

struct DeviceState {
  DeviceInfo info;
  cl::Device device;
  cl::Context context;
  cl::CommandQueue queue;
  std::mutex mutex;                                                       // guards programs
  std::map<std::pair<std::uint64_t, std::string>, cl::Program> programs;  // (source hash, options) → program
};

}  // namespace relit::detail
