// Atomic writes (temp + checked write + fsync + rename), whole-file reads, folders and stale temporaries.
#include <relit/error.hpp>
#include <relit/io/file.hpp>

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

namespace fs = std::filesystem;

namespace relit::io {

namespace {

[[noreturn]] void fail(const std::string& what, const std::string& path, int err) {
  throw IOError("cannot " + what + " '" + path + "': " + std::strerror(err));
}

std::function<void(testing::Stage, const std::string&)>& failure_hook() {
  static std::function<void(testing::Stage, const std::string&)> hook;
  return hook;
}

// Runs the test hook; its exception becomes the IOError of a failed write.
void inject(testing::Stage stage, const std::string& path) {
  if (!failure_hook()) return;
  try {
    failure_hook()(stage, path);
  } catch (const std::exception& e) {
    throw IOError("cannot write '" + path + "': " + e.what());
  }
}

void sync_directory_of(const std::string& path) {
  const fs::path target(path);
  const std::string dir = target.has_parent_path() ? target.parent_path().string() : ".";
  if (const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

// Writes all of `bytes` to `fd`, retrying short writes and EINTR; throws IOError naming `path`.
void write_all(int fd, const std::string& bytes, const std::string& path) {
  for (std::size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail("write", path, n < 0 ? errno : EIO);
    done += static_cast<std::size_t>(n);
  }
}

// The last step of every atomic file write: rename the flushed temporary over `path` (the test hook's rename
// stage first) and make the rename durable; the temporary is removed on failure.
void rename_into_place(const std::string& tmp, const std::string& path) {
  try {
    inject(testing::Stage::rename, path);
    if (::rename(tmp.c_str(), path.c_str()) != 0) fail("replace", path, errno);
  } catch (...) {
    ::unlink(tmp.c_str());
    throw;
  }
  sync_directory_of(path);
}

bool process_alive(long pid) { return pid > 0 && (::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM); }

}  // namespace

namespace testing {
void set_failure_hook(std::function<void(Stage, const std::string&)> hook) { failure_hook() = std::move(hook); }
}  // namespace testing

std::string temporary_sibling(const std::string& path) {
  static std::atomic<unsigned> counter{0};
  const fs::path p(path);
  return (p.parent_path() / ("." + p.stem().string() + ".tmp-" + std::to_string(::getpid()) + "-" +
                             std::to_string(counter++) + p.extension().string()))
      .string();
}

void replace_file(const std::string& tmp, const std::string& path) {
  try {
    // Writers that buffer (OpenImageIO) may report success while the disk is full: fsync surfaces the
    // deferred error, and an empty result is never a valid file.
    const int fd = ::open(tmp.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) fail("reopen the temporary file for", path, errno);
    struct stat st {};
    const bool synced = ::fsync(fd) == 0;
    const int err = errno;
    const bool sized = ::fstat(fd, &st) == 0;
    ::close(fd);
    if (!synced) fail("flush", path, err);
    if (!sized || st.st_size == 0) throw IOError("cannot write '" + path + "': the written file is empty (disk full?)");
  } catch (...) {
    ::unlink(tmp.c_str());
    throw;
  }
  rename_into_place(tmp, path);
}

void rename_directory(const std::string& tmp, const std::string& path) {
  inject(testing::Stage::rename, path);
  if (::rename(tmp.c_str(), path.c_str()) != 0) fail("move the finished folder into place as", path, errno);
  sync_directory_of(path);
}

void write_file_atomic(const std::string& path, const std::string& bytes) {
  const std::string tmp = temporary_sibling(path);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) fail("create a temporary file to write", path, errno);
  try {
    inject(testing::Stage::write, path);
    write_all(fd, bytes, path);
    if (::fsync(fd) != 0) fail("flush", path, errno);
  } catch (...) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw;
  }
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    fail("flush", path, err);
  }
  rename_into_place(tmp, path);  // flushed above: no second fsync, and an empty file asked for is fine
}

void append_file(const std::string& path, const std::string& bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) fail("append to", path, errno);
  try {
    write_all(fd, bytes, path);
    if (::fsync(fd) != 0) fail("flush", path, errno);
  } catch (...) {
    ::close(fd);
    throw;
  }
  if (::close(fd) != 0) fail("flush", path, errno);
}

std::string read_file(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw IOError("cannot read '" + path + "': it is a folder, not a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("read", path, errno ? errno : ENOENT);
  std::ostringstream s;
  s << in.rdbuf();
  if (in.bad()) fail("read", path, errno);
  return s.str();
}

void create_directories(const std::string& path, const std::string& what) {
  const std::string named = what + " '" + path + "'";
  std::error_code ec;
  if (fs::exists(path, ec) && !fs::is_directory(path, ec))
    throw IOError(named + " is an existing file, not a folder; choose a folder");
  fs::create_directories(path, ec);
  if (ec) throw IOError("cannot create " + named + ": " + ec.message());
  if (::access(path.c_str(), W_OK | X_OK) != 0)
    throw IOError("cannot write into " + named + ": " + std::strerror(errno));
}

long temporary_owner(const std::string& name) {
  static const std::regex pattern(R"(\..+\.(?:tmp-(\d+)-\d+(?:\.[A-Za-z0-9]+)?|(?:partial|old)-(\d+)))");
  std::smatch m;
  if (!std::regex_match(name, m, pattern)) return 0;
  const std::string digits = m[1].matched ? m[1].str() : m[2].str();
  if (digits.size() > 9) return 0;
  return std::stol(digits);
}

int remove_stale_temporaries(const std::string& dir) {
  std::error_code ec;
  int removed = 0;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const long pid = temporary_owner(it->path().filename().string());
    if (pid == 0 || pid == ::getpid() || process_alive(pid)) continue;
    std::error_code rm;
    if (fs::remove_all(it->path(), rm) > 0 && !rm) ++removed;
  }
  return removed;
}

}  // namespace relit::io
