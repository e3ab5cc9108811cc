// Videos: numbered PNG frames encoded to an MP4 (H.264) by the ffmpeg program, written atomically.
#pragma once

#include <string>

namespace relit::io {

/// Encodes the frames `frame_pattern` (a printf pattern such as "out_%04d.png", numbered from 0) at `fps` frames
/// per second to the MP4 `path`: ffmpeg writes a temporary sibling, which is renamed over `path` once complete.
/// Throws IOError naming ffmpeg when it is not on PATH, or with ffmpeg's message when it fails.
void encode_mp4(const std::string& frame_pattern, int fps, const std::string& path);

/// The full path of program `name` found on PATH, or "" when it is not there.
std::string find_program(const std::string& name);

}  // namespace relit::io
