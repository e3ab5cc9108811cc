// MP4 encoding through ffmpeg: spawned without a shell, its messages kept for the error.
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/io/video.hpp>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

extern char** environ;

namespace fs = std::filesystem;

namespace relit::io {

std::string find_program(const std::string& name) {
  const char* path = std::getenv("PATH");
  if (!path) return "";
  std::stringstream dirs(path);
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    if (dir.empty()) continue;
    const fs::path candidate = fs::path(dir) / name;
    std::error_code ec;
    if (fs::is_regular_file(candidate, ec) && ::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "";
}

void encode_mp4(const std::string& frame_pattern, int fps, const std::string& path) {
  if (fps < 1 || fps > 240) throw InvalidArgument("video frame rate must lie in [1, 240], got " + std::to_string(fps));
  const std::string ffmpeg = find_program("ffmpeg");
  if (ffmpeg.empty())
    throw IOError("cannot write the video '" + path +
                  "': the ffmpeg program is not on PATH (install it, e.g. the Debian package ffmpeg; the frames "
                  "are written)");
  const std::string tmp = temporary_sibling(path);
  const std::string log = temporary_sibling(path + ".log");
  // Even sizes for yuv420p; -y because the temporary exists only if a killed run left it.
  std::vector<std::string> args{ffmpeg,
                                "-nostdin",
                                "-y",
                                "-loglevel",
                                "error",
                                "-framerate",
                                std::to_string(fps),
                                "-start_number",
                                "0",
                                "-i",
                                frame_pattern,
                                "-vf",
                                "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                                "-c:v",
                                "libx264",
                                "-pix_fmt",
                                "yuv420p",
                                "-f",
                                "mp4",
                                tmp};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 2, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, ffmpeg.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  int status = 0;
  if (spawned == 0) ::waitpid(pid, &status, 0);
  std::string message;
  {
    std::ifstream in(log);
    std::stringstream ss;
    ss << in.rdbuf();
    message = ss.str();
    while (!message.empty() && (message.back() == '\n' || message.back() == '\r')) message.pop_back();
  }
  std::error_code ec;
  fs::remove(log, ec);
  if (spawned != 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    fs::remove(tmp, ec);
    throw IOError("ffmpeg (" + ffmpeg + ") failed to encode '" + frame_pattern + "' into '" + path + "'" +
                  (spawned != 0      ? ": cannot start it"
                   : message.empty() ? ""
                                     : ": " + message));
  }
  replace_file(tmp, path);
}

}  // namespace relit::io
