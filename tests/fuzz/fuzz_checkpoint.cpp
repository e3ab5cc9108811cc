// Fuzz target: a checkpoint file (io::load_checkpoint). A mutated file almost never keeps its checksum, which
// the reader checks first; so each input is read twice: as it is, and with its last 8 bytes replaced by the
// checksum of the rest, which takes the reader past the checksum into the header and the tensor table.
#include <relit/io/checkpoint.hpp>

#include "fuzz_common.hpp"

#include <vector>

namespace {
std::uint64_t fnv1a(const std::uint8_t* data, std::size_t n) {  // as lib/src/io/checkpoint.cpp
  std::uint64_t h = 1469598103934665603ull;
  for (std::size_t i = 0; i < n; ++i) {
    h ^= data[i];
    h *= 1099511628211ull;
  }
  return h;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = relit::fuzz::write_input("checkpoint.relit", data, size);
  relit::fuzz::expect_only_relit_errors([&] { relit::io::load_checkpoint(path); });
  if (size < 8) return 0;
  std::vector<std::uint8_t> fixed(data, data + size);
  const std::uint64_t h = fnv1a(fixed.data(), size - 8);
  for (int i = 0; i < 8; ++i) fixed[size - 8 + i] = static_cast<std::uint8_t>(h >> (8 * i));
  relit::fuzz::write_input("checkpoint.relit", fixed.data(), fixed.size());
  return relit::fuzz::expect_only_relit_errors([&] { relit::io::load_checkpoint(path); });
}
