// Whole-file reads and crash-safe writes. Every file relit writes goes through here: the bytes go to a
// temporary file next to the target, are written and checked, flushed to disk (fsync), and renamed over the
// target, so the target is always either its old self or complete. The temporary is removed on failure; the
// temporaries of killed processes are recognised by name (".NAME.tmp-PID-N.EXT") and removed by
// remove_stale_temporaries() once their process is gone.
#pragma once

#include <functional>
#include <string>

namespace relit::io {

/// Writes `bytes` to `path` atomically (see above). Throws IOError naming the path and the system's reason.
void write_file_atomic(const std::string& path, const std::string& bytes);

/// Appends `bytes` to `path` (created if missing) in one write and fsyncs it: for logs, which grow rather
/// than being replaced; a kill can at worst tear the last line. Throws IOError naming the path.
void append_file(const std::string& path, const std::string& bytes);

/// A unique temporary path next to `path` that keeps its extension (writers that pick a format by extension,
/// such as OpenImageIO, can write to it), for use with replace_file().
std::string temporary_sibling(const std::string& path);

/// Flushes the finished temporary file `tmp` to disk, checks it is not empty, renames it over `path` and makes
/// the rename durable; removes `tmp` and throws IOError on failure.
void replace_file(const std::string& tmp, const std::string& path);

/// Renames the complete folder `tmp` to `path` (which must not exist) durably; throws IOError on failure and
/// leaves `tmp` for the caller to remove.
void rename_directory(const std::string& tmp, const std::string& path);

/// The whole content of `path`. Throws IOError naming the path when it is missing, a folder or unreadable.
std::string read_file(const std::string& path);

/// Creates folder `path` and its parents if needed. Throws IOError naming the path and the reason when it
/// exists as a file, is too long, or cannot be created or written to.
void create_directories(const std::string& path, const std::string& what);

/// Whether `name` is a temporary that temporary_sibling() or a partial folder of `prefix` made for a process
/// with the given id: ".NAME.tmp-PID-N[.EXT]" or ".NAME.partial-PID" / ".NAME.old-PID"; returns the PID or 0.
long temporary_owner(const std::string& name);

/// Removes, in folder `dir`, the temporaries (files and partial folders, see temporary_owner) whose process
/// is no longer running: what killed runs left behind. Anything else is left alone. Returns how many.
int remove_stale_temporaries(const std::string& dir);

/// Test hooks: failure injection for the atomic writers.
namespace testing {
enum class Stage {
  write,   ///< the temporary file exists and is about to be filled
  rename,  ///< the temporary file or folder is complete and about to be renamed over the target
};
/// `hook(stage, target)` runs at each stage of every atomic write; a throw there makes that write fail as a
/// full disk or a failed rename would. Pass an empty function to remove it. Not thread-safe: tests only.
void set_failure_hook(std::function<void(Stage, const std::string& target)> hook);
}  // namespace testing

}  // namespace relit::io
