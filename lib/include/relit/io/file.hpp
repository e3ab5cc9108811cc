// Whole-file reads and crash-safe writes.
#pragma once

#include <string>

namespace relit::io {

/// Writes `bytes` to `path` so that `path` is either its old self or complete: the data goes to a temporary
/// file in the same folder, is flushed to disk (fsync), and is renamed over `path`. Throws IOError naming the
/// path and the system's reason; on failure no temporary file is left behind.
void write_file_atomic(const std::string& path, const std::string& bytes);

/// A unique temporary path next to `path` that keeps its extension (writers that pick a format by extension,
/// such as OpenImageIO, can write to it), for use with replace_file().
std::string temporary_sibling(const std::string& path);

/// Renames the finished temporary file `tmp` over `path` and makes the rename durable; removes `tmp` and
/// throws IOError on failure.
void replace_file(const std::string& tmp, const std::string& path);

/// The whole content of `path`. Throws IOError naming the path when it is missing or unreadable.
std::string read_file(const std::string& path);

}  // namespace relit::io
