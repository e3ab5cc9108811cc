// Checkpoints (docs/design.md §7): one self-describing file per checkpoint, no pickle.
//
//   offset 0   8 bytes  magic "RELITCKP"
//              4 bytes  format version (little-endian uint32, currently 1)
//              8 bytes  header length H (little-endian uint64)
//              H bytes  JSON header: {"format_version", "library_version", "tensors": [{"name", "count",
//                       "offset"}...], plus whatever the writer adds: resolved config, step, RNG state, ...}
//              ...      the tensors, little-endian float32, at their offsets (from the end of the header)
//   last       8 bytes  FNV-1a 64 checksum of everything before it
//
// Written atomically (temporary file + fsync + rename): a crash never leaves a half-written checkpoint
// where a good one was. Loading checks magic, version, sizes and checksum, and says which is wrong.
#pragma once

#include <relit/config.hpp>

#include <map>
#include <string>
#include <vector>

namespace relit::io {

struct Checkpoint {
  /// Free-form metadata (config, step, RNG state...). The keys "format_version", "library_version" and
  /// "tensors" are managed by save/load.
  Json header = Json::object();
  /// Named float tensors (parameters, optimiser moments...), stored in name order.
  std::map<std::string, std::vector<float>> tensors;
};

constexpr std::uint32_t kCheckpointVersion = 1;

void save_checkpoint(const std::string& path, const Checkpoint& checkpoint);
Checkpoint load_checkpoint(const std::string& path);

}  // namespace relit::io
