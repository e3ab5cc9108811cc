// Exporting a learned medium: OpenVDB grids that relit's scene loader and OpenVDB's own tools read back.
#include "test_support.hpp"

#include <relit/method/export.hpp>
#include <relit/scene/scene.hpp>
#include <relit/scene/vdb.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>

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

}  // namespace
}  // namespace relit
