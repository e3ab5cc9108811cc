// Finding kernel sources and resolving their #includes.
#include "cl/kernel_sources.hpp"

#include "embedded_files.hpp"

#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/log.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

namespace relit::detail {

namespace {

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
  for (const auto& k : embedded_kernels())
    if (name == k.name) return k.text;
  std::string message = "no kernel source '" + name + "'";
  if (!included_from.empty()) message += " (included from " + included_from + ")";
  message += "; relit has:";
  for (const auto& k : embedded_kernels()) message += std::string(" ") + k.name;
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
  for (const auto& k : embedded_kernels()) {
    const std::string name = k.name;
    if (name.size() > 3 && name.compare(name.size() - 3, 3, ".cl") == 0) files.push_back(name);
  }
  return files;  // the generator emits them sorted
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
