// Interop: a learned medium exported as OpenVDB grids that relit's scene loader and OpenVDB's own tools read
// back and as a Mitsuba 3 scene, and relighting videos (PNG frames and an MP4 that ffprobe reads).
#include "test_support.hpp"

#include <relit/io/image.hpp>
#include <relit/method/export.hpp>
#include <relit/method/render_video.hpp>
#include <relit/scene/scene.hpp>
#include <relit/scene/vdb.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

namespace relit {
namespace {

std::unique_ptr<method::Model> tiny_model(const std::string& method = "ours") {
  auto model = method::create_model(test::test_device(), method, test::tiny_ours_model());
  model->initialize(7);
  return model;
}

// The output of a shell command and its exit status.
std::pair<std::string, int> shell(const std::string& command) {
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return {"popen failed", -1};
  std::string out;
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), int(buf.size()), pipe)) out += buf.data();
  return {out, ::pclose(pipe)};
}

float median(std::vector<float> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

TEST(Export, VdbRoundTripGivesTheModelsDensityAlbedoAndG) {
  const auto model = tiny_model();
  const int res = 24;
  const method::MediumSamples samples = method::sample_medium(*model, res);
  ASSERT_EQ(samples.sigma.size(), std::size_t(res) * res * res);
  method::VdbExportSettings s;
  s.resolution = res;
  s.threshold = median(samples.sigma);  // half the voxels stay inactive
  s.run = "unit-run";
  test::TempDir dir("export");
  const std::string path = (dir.path() / "medium.vdb").string();
  const method::VdbExportStats stats = method::export_vdb(*model, path, s);
  EXPECT_GT(stats.active_voxels, samples.sigma.size() / 4);
  EXPECT_LT(stats.active_voxels, samples.sigma.size() * 3 / 4);

  const Scene scene = Scene::builtin_or_file(path);
  ASSERT_TRUE(scene.medium.has_value());
  const Medium& m = *scene.medium;
  ASSERT_EQ(m.density.nx, res);
  EXPECT_EQ(m.density_scale, 1.0f);
  ASSERT_EQ(m.albedo_grid.channels, 3);
  EXPECT_NEAR(m.g, stats.mean_g, 1e-6);
  double max_err = 0.0, max_albedo_err = 0.0;
  std::size_t active = 0;
  for (std::size_t v = 0; v < samples.sigma.size(); ++v) {
    const float sigma = samples.sigma[v];
    const bool on = sigma > s.threshold;
    active += on;
    max_err = std::max(max_err, std::abs(double(m.density.values[v]) - (on ? sigma : 0.0f)));
    for (int c = 0; on && c < 3; ++c)
      max_albedo_err =
          std::max(max_albedo_err, std::abs(double(m.albedo_grid.values[v * 3 + c]) - samples.albedo[v * 3 + c]));
  }
  EXPECT_EQ(active, stats.active_voxels);
  EXPECT_EQ(max_err, 0.0) << "max |imported - model| of the density (the same voxel centres: exact)";
  EXPECT_EQ(max_albedo_err, 0.0);
  std::printf("round trip at %d^3: max |density error| %.3g (max sigma %.3g), max |albedo error| %.3g\n", res, max_err,
              stats.max_sigma, max_albedo_err);

  const VdbInfo info = read_vdb_info(path);
  EXPECT_TRUE(info.has("density") && info.has("albedo") && info.has("g"));
  EXPECT_EQ(info.resolution, res);
  EXPECT_EQ(info.metadata.at("relit_run"), "unit-run");
  EXPECT_EQ(info.metadata.at("relit_method"), "ours");
}

// OpenVDB's own reader (vdb_print, Debian package libopenvdb-tools, installed by scripts/setup.sh) lists the
// grids; without the tool the test fails.
TEST(Export, OpenVdbsOwnToolReadsTheFile) {
  const auto model = tiny_model();
  test::TempDir dir("export-print");
  const std::string path = (dir.path() / "medium.vdb").string();
  method::VdbExportSettings s;
  s.resolution = 16;
  s.run = "printed";
  method::export_vdb(*model, path, s);
  const auto [out, status] = shell("vdb_print -l -m '" + path + "'");
  ASSERT_EQ(status, 0) << "vdb_print (Debian package libopenvdb-tools; scripts/setup.sh installs it) failed or is "
                          "missing:\n"
                       << out;
  for (const char* word : {"density", "albedo", "relit_method", "ours", "printed", "float", "vec3s"})
    EXPECT_NE(out.find(word), std::string::npos) << word << " missing from vdb_print's output:\n" << out;
}

TEST(Export, BadOutputsAndModelsAreClearErrorsThatDamageNothing) {
  const auto model = tiny_model();
  test::TempDir dir("export-bad");
  const std::string missing = (dir.path() / "no-such-folder" / "m.vdb").string();
  try {
    method::export_vdb(*model, missing);
    FAIL() << "wrote into a missing folder";
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find("no-such-folder"), std::string::npos) << e.what();
  }
  method::VdbExportSettings s;
  s.resolution = 4;
  EXPECT_THROW(method::export_vdb(*model, (dir.path() / "m.vdb").string(), s), InvalidArgument);
  // An existing file survives a failed write whole, and no temporary is left.
  const std::string existing = (dir.path() / "kept.vdb").string();
  std::ofstream(existing) << "precious";
  const auto before = test::snapshot(dir.path());
  {
    test::FailWrites fail(io::testing::Stage::rename, "kept.vdb");
    s.resolution = 8;
    EXPECT_THROW(method::export_vdb(*model, existing, s), std::exception);
  }
  EXPECT_EQ(test::snapshot(dir.path()), before);
  // Solids (ours_brdf) have no medium to export.
  auto brdf = method::create_model(test::test_device(), "ours_brdf", test::tiny_ours_model());
  EXPECT_THROW(method::sample_medium(*brdf, 8), InvalidArgument);
}

// The Mitsuba scene's files; its rendering is compared with relit's in tests/python/test_interop.py.
TEST(Export, MitsubaSceneFolderIsCompleteOrAbsent) {
  const auto model = tiny_model();
  test::TempDir dir("export-mitsuba");
  method::MitsubaExportSettings s;
  s.resolution = 8;
  s.camera = Camera::look_at({0, -4, 1}, {0, 0, 0}, {0, 0, 1}, 0.7f, 10, 6);
  s.light = PointLight{{2, -3, 2}, {100, 200, 300}};
  const std::string out = (dir.path() / "scene").string();
  const auto stats = method::export_mitsuba(*model, out, s);
  const std::string density = io::read_file(out + "/density.vol"), albedo = io::read_file(out + "/albedo.vol");
  EXPECT_EQ(density.size(), 48u + 8 * 8 * 8 * 4);
  EXPECT_EQ(albedo.size(), 48u + 8 * 8 * 8 * 3 * 4);
  EXPECT_EQ(density.substr(0, 4), std::string("VOL\x03"));
  const std::string xml = io::read_file(out + "/scene.xml");
  for (const char* part : {"<integrator type=\"volpath\">", "<bsdf type=\"null\"/>", "name=\"interior\"",
                           "value=\"density.vol\"", "value=\"albedo.vol\"", "name=\"width\" value=\"10\"",
                           "name=\"height\" value=\"6\"", "value=\"100, 200, 300\"", "<rfilter type=\"box\"/>"})
    EXPECT_NE(xml.find(part), std::string::npos) << part << " missing from scene.xml:\n" << xml;
  EXPECT_GT(stats.max_sigma, 0.0f);
  // An existing folder is refused; a failed write leaves neither the folder nor a temporary.
  EXPECT_THROW(method::export_mitsuba(*model, out, s), IOError);
  {
    test::FailWrites fail(io::testing::Stage::rename, "albedo.vol");
    EXPECT_THROW(method::export_mitsuba(*model, (dir.path() / "other").string(), s), std::exception);
  }
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) names.push_back(e.path().filename().string());
  EXPECT_EQ(names, std::vector<std::string>{"scene"});
}

// A light orbit of 4 frames at 16 x 16: 4 numbered PNGs that differ as the light moves, and an MP4 of 4 frames
// (ffprobe counts them; ffmpeg and ffprobe come with the Debian package ffmpeg, which scripts/setup.sh installs).
TEST(Video, LightOrbitWritesNumberedFramesAndAnMp4) {
  const auto model = tiny_model();
  test::TempDir dir("video");
  const std::string prefix = (dir.path() / "orbit").string();
  method::Keyframe start;
  start.light = {3, 0, 1};
  method::VideoSettings vs;
  vs.width = vs.height = 16;
  vs.fps = 8;
  std::vector<std::uint64_t> seen;
  const auto paths = method::render_video(*model, method::orbit_light(start, 4), prefix, vs, [&](const Progress& p) {
    seen.push_back(p.done);
    return p.total == 4 && p.unit == "frames";
  });
  ASSERT_EQ(paths.size(), 4u);
  EXPECT_EQ(seen.back(), 4u);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(paths[i], prefix + "_000" + std::to_string(i) + ".png");
  std::vector<Image> frames;
  for (const auto& p : paths) frames.push_back(read_image(p));
  for (int i = 1; i < 4; ++i) {
    ASSERT_EQ(frames[i].width, 16);
    double diff = 0.0;
    for (std::size_t v = 0; v < frames[0].pixels.size(); ++v)
      diff += std::abs(frames[i].pixels[v] - frames[0].pixels[v]);
    EXPECT_GT(diff / frames[0].pixels.size(), 1e-3) << "frame " << i << " looks like frame 0: the light did not move";
  }
  const auto [count, status] = shell(
      "ffprobe -v error -count_frames -select_streams v:0 -show_entries "
      "stream=nb_read_frames,width,height -of csv=p=0 '" +
      prefix + ".mp4'");
  ASSERT_EQ(status, 0) << "ffprobe failed or is missing (Debian package ffmpeg):\n" << count;
  EXPECT_EQ(count, "16,16,4\n");
  for (const auto& e : std::filesystem::directory_iterator(dir.path()))  // no temporaries or logs left
    EXPECT_NE(e.path().filename().string()[0], '.') << e.path();
}

// A PATH without ffmpeg that still has the linker: PoCL links every kernel it compiles with `ld` from PATH, so a
// kernel compiled for the first time while PATH is stripped fails to build (its cache decides whether one is).
std::string path_without_ffmpeg(const std::filesystem::path& dir) {
  const auto bin = dir / "bin";
  std::filesystem::create_directories(bin);
  const char* path = std::getenv("PATH");
  std::stringstream entries(path ? path : "");
  for (std::string entry; std::getline(entries, entry, ':');) {
    const auto ld = std::filesystem::path(entry) / "ld";
    if (!entry.empty() && std::filesystem::exists(ld)) {
      std::filesystem::create_symlink(ld, bin / "ld");
      break;
    }
  }
  return bin.string();
}

TEST(Video, WithoutFfmpegTheErrorNamesItAndTheFramesStay) {
  const auto model = tiny_model();
  test::TempDir dir("video-noffmpeg");
  const std::string prefix = (dir.path() / "v").string();
  method::VideoSettings vs;
  vs.width = vs.height = 8;
  {
    test::ScopedEnv path("PATH", path_without_ffmpeg(dir.path()));
    try {
      method::render_video(*model, method::orbit_camera({}, 2), prefix, vs);
      FAIL() << "no error without ffmpeg";
    } catch (const IOError& e) {
      EXPECT_NE(std::string(e.what()).find("ffmpeg"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("v.mp4"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(std::filesystem::exists(prefix + "_0001.png"));
  EXPECT_FALSE(std::filesystem::exists(prefix + ".mp4"));
  // Bad frames are refused before anything is rendered.
  method::Keyframe inside;
  inside.light = {0, 0, 0.5f};
  EXPECT_THROW(method::render_video(*model, {inside}, (dir.path() / "w").string(), vs), InvalidArgument);
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "w_0000.png"));
  EXPECT_THROW(method::orbit_light({}, 0), InvalidArgument);
}

TEST(Video, KeyframeFilesKeepUnsetKeysAndNameBadEntries) {
  test::TempDir dir("keyframes");
  const std::string path = (dir.path() / "path.json").string();
  std::ofstream(path) << R"([{"eye": [0, -5, 1], "light": [3, 0, 2], "intensity": 900}, {"light": [0, 3, 2]}])";
  const auto k = method::read_keyframes(path);
  ASSERT_EQ(k.size(), 2u);
  EXPECT_EQ(k[1].eye, (Float3{0, -5, 1}));
  EXPECT_EQ(k[1].light, (Float3{0, 3, 2}));
  EXPECT_EQ(k[1].intensity, (Float3{900, 900, 900}));
  std::ofstream(path) << R"([{"eye": [0, -5]}])";
  try {
    method::read_keyframes(path);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("frame 0: \"eye\""), std::string::npos) << e.what();
  }
  std::ofstream(path) << R"([{"eyes": [0, -5, 1]}])";
  EXPECT_THROW(method::read_keyframes(path), InvalidArgument);
}

}  // namespace
}  // namespace relit
