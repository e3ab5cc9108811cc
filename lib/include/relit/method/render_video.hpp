// Relighting videos: a model's frames along a camera or light path, written as numbered PNGs and an MP4
// (docs/interop.md, "Relighting videos").
//
//   relit::method::Keyframe start{{0, -4, 1}, {0, 0, 0}, {3, -3, 2}, {800, 800, 800}};
//   relit::method::VideoSettings settings;                      // 128 x 128, 24 frames per second
//   relit::method::render_video(*model, relit::method::orbit_light(start, 48), "out/cloud", settings);
//   // out/cloud_0000.png ... out/cloud_0047.png and out/cloud.mp4
#pragma once

#include <relit/method/render_image.hpp>

#include <string>
#include <vector>

namespace relit::method {

/// One frame's camera (eye, target; z up) and point light.
struct Keyframe {
  Float3 eye{0, -4, 1};
  Float3 target{0, 0, 0};
  Float3 light{0, -3, 3};
  Float3 intensity{600, 600, 600};  ///< W/sr per channel
};

/// `n` frames of the camera going once around the vertical (z) axis through the target, from `start`.
std::vector<Keyframe> orbit_camera(const Keyframe& start, int n);
/// `n` frames of the light going once around the z axis through the box centre, from `start`.
std::vector<Keyframe> orbit_light(const Keyframe& start, int n);
/// The frames of a JSON file: a list of objects with any of "eye", "target", "light" ([x, y, z]) and
/// "intensity" (a number or [r, g, b]); a key left out keeps the previous frame's value (the first frame's:
/// `start`'s). InvalidArgument naming the file and the frame for a bad entry; IOError for a missing file.
std::vector<Keyframe> read_keyframes(const std::string& path, const Keyframe& start = {});

/// How render_video renders and encodes.
struct VideoSettings {
  int width = 128, height = 128;
  float fov = 0.8f;  ///< horizontal field of view, radians
  ImageRenderSettings render;
  int fps = 24;
  bool mp4 = true;  ///< also encode PREFIX.mp4 (through ffmpeg)
};

/// Renders every keyframe to PREFIX_0000.png, PREFIX_0001.png, ... (8-bit sRGB, each written atomically) and,
/// with settings.mp4, encodes them to PREFIX.mp4 (io::encode_mp4: a temporary renamed once complete; IOError
/// naming ffmpeg when it is missing). Progress is counted in frames. Returns the frame paths.
std::vector<std::string> render_video(const Model& model, const std::vector<Keyframe>& frames,
                                      const std::string& prefix, const VideoSettings& settings = {},
                                      const ProgressCallback& progress = {});

}  // namespace relit::method
