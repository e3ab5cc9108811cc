// Finding kernel sources and resolving their #includes.
#include "cl/kernel_sources.hpp"

#include "embedded_files.hpp"

#include <relit/cl/device.hpp>
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/log.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <set>
#include <sstream>

namespace relit::detail {

namespace {

// The sources added with relit::add_kernel_source(), by name.
struct AddedSources {
  std::mutex mutex;
  std::map<std::string, std::string> files;
};

AddedSources& added_sources() {
  static AddedSources added;  // constructed on first use: sources may be added by static initialisers
  return added;
}

const char* embedded_text(const std::string& name) {
  for (const auto& k : embedded_kernels())
    if (name == k.name) return k.text;
  return nullptr;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() > suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string raw_source(const std::string& name, const std::string& included_from) {
  if (const char* dir = std::getenv("RELIT_KERNEL_DIR"); dir && *dir) {
    const std::filesystem::path path = std::filesystem::path(dir) / name;
    if (std::filesystem::exists(path)) {
      static bool announced = false;
      if (!announced) {
        log_info(std::string("reading kernels from RELIT_KERNEL_DIR=") + dir);
        announced = true;
      }
      return io::read_file(path.string());
    }
  }
  if (const char* text = embedded_text(name)) return text;
  auto& added = added_sources();
  std::lock_guard<std::mutex> lock(added.mutex);
  if (auto it = added.files.find(name); it != added.files.end()) return it->second;
  std::string message = "no kernel source '" + name + "'";
  if (!included_from.empty()) message += " (included from " + included_from + ")";
  message += "; relit has:";
  for (const auto& k : embedded_kernels()) message += std::string(" ") + k.name;
  if (!added.files.empty()) {
    message += "; added:";
    for (const auto& [file, text] : added.files) message += " " + file;
  }
  throw IOError(message);
}

void append_resolved(const std::string& name, const std::string& included_from, std::set<std::string>& seen,
                     std::string& out) {
  if (!seen.insert(name).second) return;  // headers are included once, like #pragma once
  static const std::regex include_line(R"(^\s*#\s*include\s*"([^"]+)\"\s*$)");
  std::istringstream lines(raw_source(name, included_from));
  std::string line;
  int number = 0;
  out += "#line 1 \"" + name + "\"\n";
  while (std::getline(lines, line)) {
    ++number;
    std::smatch match;
    if (std::regex_match(line, match, include_line)) {
      append_resolved(match[1].str(), name + ":" + std::to_string(number), seen, out);
      out += "#line " + std::to_string(number + 1) + " \"" + name + "\"\n";
    } else {
      out += line;
      out += '\n';
    }
  }
}

}  // namespace

std::string resolve_kernel_source(const std::string& file) {
  std::set<std::string> seen;
  std::string out;
  append_resolved(file, "", seen, out);
  return out;
}

std::vector<std::string> program_files() {
  std::vector<std::string> files;
  for (const auto& k : embedded_kernels())
    if (ends_with(k.name, ".cl")) files.push_back(k.name);  // the generator emits them sorted
  auto& added = added_sources();
  std::lock_guard<std::mutex> lock(added.mutex);
  for (const auto& [name, text] : added.files)  // sorted by the map, after relit's own
    if (ends_with(name, ".cl")) files.push_back(name);
  return files;
}

std::uint64_t fnv1a(const std::string& text) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

}  // namespace relit::detail

namespace relit {

void add_kernel_source(const std::string& name, const std::string& text) {
  if (name.find_first_of("/\\") != std::string::npos ||
      !(detail::ends_with(name, ".cl") || detail::ends_with(name, ".clh")))
    throw InvalidArgument("add_kernel_source: '" + name + "' is not a kernel file name (x.cl or x.clh, no folder)");
  if (detail::embedded_text(name))
    throw InvalidArgument("add_kernel_source: relit already has a kernel source '" + name + "'; choose another name");
  auto& added = detail::added_sources();
  std::lock_guard<std::mutex> lock(added.mutex);
  const auto [it, inserted] = added.files.emplace(name, text);
  if (!inserted && it->second != text)
    throw InvalidArgument("add_kernel_source: '" + name + "' was already added with another text");
}

}  // namespace relit
