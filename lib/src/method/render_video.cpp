// Relighting videos: frames along camera and light paths, PNGs and an MP4.
#include <relit/parallel.hpp>
#include <relit/config.hpp>
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/io/video.hpp>
#include <relit/method/render_video.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>

namespace fs = std::filesystem;

namespace relit::method {

namespace {

constexpr double kTwoPi = 6.283185307179586;

Float3 rotate_z(const Float3& p, const Float3& centre, double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  const double x = p[0] - centre[0], y = p[1] - centre[1];
  return {float(centre[0] + c * x - s * y), float(centre[1] + s * x + c * y), p[2]};
}

void check_count(int n) {
  if (n < 1 || n > 100000) throw InvalidArgument("a video needs 1 to 100000 frames, got " + std::to_string(n));
}

Float3 read_triple(const Json& j, const std::string& where, bool scalar_ok) {
  if (scalar_ok && j.is_number() && std::isfinite(j.get<double>())) {
    const float v = j.get<float>();
    return {v, v, v};
  }
  bool ok = j.is_array() && j.size() == 3;
  Float3 out{};
  for (std::size_t i = 0; ok && i < 3; ++i) {
    ok = j[i].is_number() && std::isfinite(j[i].get<double>());
    if (ok) out[i] = j[i].get<float>();
  }
  if (!ok)
    throw InvalidArgument(where + " must be " + (scalar_ok ? "a number or " : "") +
                          "[x, y, z] of finite numbers, got " + j.dump());
  return out;
}

}  // namespace

std::vector<Keyframe> orbit_camera(const Keyframe& start, int n) {
  check_count(n);
  std::vector<Keyframe> out(n, start);
  for (int i = 0; i < n; ++i) out[i].eye = rotate_z(start.eye, start.target, kTwoPi * i / n);
  return out;
}

std::vector<Keyframe> orbit_light(const Keyframe& start, int n) {
  check_count(n);
  std::vector<Keyframe> out(n, start);
  for (int i = 0; i < n; ++i) out[i].light = rotate_z(start.light, {0, 0, 0}, kTwoPi * i / n);
  return out;
}

std::vector<Keyframe> read_keyframes(const std::string& path, const Keyframe& start) {
  const Json j = parse_json(io::read_file(path), "keyframe file '" + path + "'");
  if (!j.is_array() || j.empty())
    throw InvalidArgument("keyframe file '" + path +
                          "' must hold a non-empty list of {\"eye\", \"target\", \"light\", \"intensity\"} objects");
  std::vector<Keyframe> out;
  Keyframe k = start;
  for (std::size_t i = 0; i < j.size(); ++i) {
    const std::string where = "keyframe file '" + path + "', frame " + std::to_string(i);
    if (!j[i].is_object()) throw InvalidArgument(where + " must be an object, got " + j[i].dump());
    for (const auto& [key, value] : j[i].items()) {
      if (key == "eye")
        k.eye = read_triple(value, where + ": \"eye\"", false);
      else if (key == "target")
        k.target = read_triple(value, where + ": \"target\"", false);
      else if (key == "light")
        k.light = read_triple(value, where + ": \"light\"", false);
      else if (key == "intensity")
        k.intensity = read_triple(value, where + ": \"intensity\"", true);
      else
        throw InvalidArgument(where + ": unknown key \"" + key + "\"; the keys are eye, target, light, intensity");
    }
    out.push_back(k);
  }
  if (out.size() > 100000) check_count(int(std::min<std::size_t>(out.size(), 1u << 30)));
  return out;
}

std::vector<std::string> render_video(const Model& model, const std::vector<Keyframe>& frames,
                                      const std::string& prefix, const VideoSettings& settings,
                                      const ProgressCallback& progress) {
  check_count(int(std::min<std::size_t>(frames.size(), 1u << 30)));
  if (settings.width < 1 || settings.height < 1 || settings.width > 16384 || settings.height > 16384)
    throw InvalidArgument("video frames must be 1 to 16384 pixels wide and high");
  const fs::path parent = fs::absolute(prefix).parent_path();
  if (!fs::is_directory(parent))
    throw IOError("cannot write the video '" + prefix + "': the folder '" + parent.string() + "' does not exist");
  // Every camera and light is checked before the first frame is rendered.
  std::vector<std::pair<Camera, PointLight>> views;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const Keyframe& k = frames[i];
    try {
      PointLight light{k.light, k.intensity};
      light.validate();
      views.emplace_back(Camera::look_at(k.eye, k.target, {0, 0, 1}, settings.fov, settings.width, settings.height),
                         light);
    } catch (const InvalidArgument& e) {
      throw InvalidArgument("video frame " + std::to_string(i) + ": " + e.what());
    }
  }
  // Under MPI the frames are shared out over the ranks; rank 0 writes them all (relit/parallel.hpp).
  const bool writer = parallel::rank() == 0;
  ProgressTracker tracker(writer ? progress : ProgressCallback(), frames.size(), "frames");
  std::vector<std::string> paths;
  char suffix[32];
  const auto render = [&](std::size_t i) {
    return render_image(model, views[i].first, views[i].second, settings.render).pixels;
  };
  const auto write = [&](std::size_t i, std::vector<float>&& pixels) {
    Image img(settings.width, settings.height, 3);
    img.pixels = std::move(pixels);
    std::snprintf(suffix, sizeof suffix, "_%04zu.png", i);
    paths.push_back(prefix + suffix);
    write_image(paths.back(), img);
    tracker.update(i + 1, "frame " + std::to_string(i));
  };
  tracker.update(0, "frame 0");
  parallel::share_out(
      views.size(), [&](std::size_t) { return std::size_t(settings.width) * settings.height * 3; }, render, write);
  if (!writer) return paths;
  if (settings.mp4) io::encode_mp4(prefix + "_%04d.png", settings.fps, prefix + ".mp4");
  return paths;
}

}  // namespace relit::method
