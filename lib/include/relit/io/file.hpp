// Whole-file reads and crash-safe writes.
#pragma once

#include <string>

namespace relit::io {

/// Writes `bytes` to `path` so that `path` is either its old self or complete: the data goes to a temporary
/// file in the same folder, is flushed to disk (fsync), and is renamed over `path`. Throws IOError naming the
/// path and the system's reason; on failure no temporary file is left behind.
void write_file_atomic(const std::string& path, const std::string& bytes);

/// The whole content of `path`. Throws IOError naming the path when it is missing or unreadable.
std::string read_file(const std::string& path);

}  // namespace relit::io
