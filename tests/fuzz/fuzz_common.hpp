// What the fuzz targets share: a scratch folder for the inputs of readers that take a path, and the one
// expected failure, relit::Error. Any other exception escapes LLVMFuzzerTestOneInput and aborts (a finding),
// as do crashes, hangs and sanitizer reports.
#pragma once

#include <relit/error.hpp>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

namespace relit::fuzz {

/// A folder of this process's own under $TMPDIR (scripts/fuzz.sh points it into the build tree), removed at exit.
inline const std::filesystem::path& scratch_dir() {
  struct Dir {
    std::filesystem::path path;
    Dir() {
      std::string tmpl = (std::filesystem::temp_directory_path() / "relit-fuzz-XXXXXX").string();
      if (!mkdtemp(tmpl.data())) std::abort();
      path = tmpl;
    }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Dir dir;
  return dir.path;
}

/// Writes the input to scratch_dir()/name (replacing it) and returns the path.
inline std::string write_input(const std::string& name, const std::uint8_t* data, std::size_t size) {
  const std::string path = (scratch_dir() / name).string();
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!f.flush()) std::abort();
  return path;
}

/// Runs `f`; a relit::Error is an expected outcome.
template <class F>
int expect_only_relit_errors(F&& f) {
  try {
    f();
  } catch (const relit::Error&) {}
  return 0;
}

}  // namespace relit::fuzz
