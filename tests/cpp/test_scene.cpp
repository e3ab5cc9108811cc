// Scenes: JSON parsing and its errors, grids and majorants, procedural generators, cameras, environment
// sampling tables (host side), OpenVDB import.
#include "test_support.hpp"

#include <relit/scene/procedural.hpp>
#include <relit/scene/scene.hpp>
#include <relit/scene/vdb.hpp>

#include <cmath>
#include <fstream>
#include <random>

namespace relit {

namespace {
using test::kPi;

template <class E>
std::string error_of(const Json& j) {
  try {
    Scene::from_json(j);
  } catch (const E& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error for " << j.dump();
  return "";
}
}  // namespace

TEST(Scene, BuiltinScenesParseAndResolveEveryDefault) {
  for (const auto& name : Scene::builtin_names()) {
    const Scene s = Scene::from_json(Scene::builtin_json(name, 3, 16));
    EXPECT_TRUE(s.medium || s.solid) << name;
    // The resolved description rebuilds the same scene.
    const Scene again = Scene::from_json(s.description);
    if (s.medium) {
      EXPECT_EQ(again.medium->density.values, s.medium->density.values) << name;
      EXPECT_EQ(again.medium->g, s.medium->g);
    }
    if (s.solid) {
      EXPECT_EQ(again.solid->sdf.values, s.solid->sdf.values) << name;
    }
  }
  const Scene blobs = Scene::from_json(Scene::builtin_json("blobs", 1, 16));
  EXPECT_FALSE(blobs.medium->albedo_grid.empty());  // spatially varying albedo
  EXPECT_EQ(blobs.description["medium"]["albedo"], "grid");
}

TEST(Scene, BadInputGivesConfigErrorsWithPointers) {
  Json j = Scene::builtin_json("cloud", 0, 16);
  j["medium"]["colour"] = 1;
  EXPECT_NE(error_of<ConfigError>(j).find("unknown key 'colour'"), std::string::npos);
  j = Scene::builtin_json("cloud", 0, 16);
  j["medium"]["g"] = 1.0;
  EXPECT_NE(error_of<ConfigError>(j).find("/medium/g"), std::string::npos);
  j["medium"]["g"] = -1.5;
  EXPECT_NE(error_of<ConfigError>(j).find("/medium/g"), std::string::npos);
  j = Scene::builtin_json("cloud", 0, 16);
  j["lights"] = Json::array({{{"position", {0, 0, 4}}, {"intensity", {100, -1, 100}}}});
  EXPECT_NE(error_of<ConfigError>(j).find("/lights/0/intensity"), std::string::npos);
  j = Scene::builtin_json("cloud", 0, 16);
  j["medium"]["source"]["type"] = "fog";
  EXPECT_NE(error_of<ConfigError>(j).find("valid types"), std::string::npos);
  EXPECT_NE(error_of<ConfigError>(Json::object()).find("needs a \"medium\" or a \"solid\""), std::string::npos);
  j = Scene::builtin_json("cloud", 0, 16);
  j["environment"] = {{"file", "no-such-map.exr"}};
  EXPECT_NE(error_of<IOError>(j).find("no-such-map.exr"), std::string::npos);
  j = Scene::builtin_json("cloud", 0, 16);
  j["medium"]["source"] = {{"type", "vdb"}, {"file", "no-such.vdb"}};
  EXPECT_NE(error_of<IOError>(j).find("no-such.vdb"), std::string::npos);
  j = Scene::builtin_json("cloud", 0, 16);
  j["cameras"] = Json::array({{{"camera_angle_x", 0.8}, {"transform_matrix", {{1, 0, 0}}}}});
  EXPECT_NE(error_of<ConfigError>(j).find("/cameras/0/transform_matrix"), std::string::npos);
}

TEST(Scene, CorruptVdbAndEnvironmentFilesGiveIOErrors) {
  test::TempDir dir("scene");
  std::ofstream(dir.path() / "bad.vdb") << "not a vdb";
  std::ofstream(dir.path() / "bad.exr") << "not an exr";
  Json j = Scene::builtin_json("cloud", 0, 16);
  j["medium"]["source"] = {{"type", "vdb"}, {"file", "bad.vdb"}};
  EXPECT_THROW(Scene::from_json(j, dir.path().string()), IOError);
  j = Scene::builtin_json("cloud", 0, 16);
  j["environment"] = {{"file", "bad.exr"}};
  EXPECT_THROW(Scene::from_json(j, dir.path().string()), IOError);
}

TEST(Grid, TrilinearLookupInterpolatesVoxelCentresAndClampsAtEdges) {
  Grid g(4, 3, 2, 1);
  std::mt19937 rng(1);
  for (auto& v : g.values) v = std::uniform_real_distribution<float>(0, 1)(rng);
  const Float3 c = g.centre(1, 2, 0);
  EXPECT_NEAR(g.sample(c[0], c[1], c[2]), g.at(1, 2, 0), 1e-6);
  const Float3 a = g.centre(1, 1, 1), b = g.centre(2, 1, 1);
  EXPECT_NEAR(g.sample(0.5 * (a[0] + b[0]), a[1], a[2]), 0.5 * (g.at(1, 1, 1) + g.at(2, 1, 1)), 1e-6);
  EXPECT_NEAR(g.sample(-1.0, -1.0, -1.0), g.at(0, 0, 0), 1e-6);  // clamped to the corner voxel
}

TEST(Grid, MajorantBoundsEveryLookupInItsCell) {
  const Grid d = make_cloud(24, 5).density;
  const Grid m = majorant_grid(d, 3.0f, 4);
  ASSERT_EQ(m.nx, 6);
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int s = 0; s < 20000; ++s) {
    const double x = u(rng), y = u(rng), z = u(rng);
    const int i = std::min(int((x + 1) / 2 * m.nx), m.nx - 1), j = std::min(int((y + 1) / 2 * m.ny), m.ny - 1),
              k = std::min(int((z + 1) / 2 * m.nz), m.nz - 1);
    ASSERT_LE(3.0 * d.sample(x, y, z), m.at(i, j, k) + 1e-6) << x << " " << y << " " << z;
  }
}

TEST(Procedural, GeneratorsAreDeterministicAndSeedDependent) {
  EXPECT_EQ(make_cloud(16, 1).density.values, make_cloud(16, 1).density.values);
  EXPECT_NE(make_cloud(16, 1).density.values, make_cloud(16, 2).density.values);
  EXPECT_EQ(make_smoke(16, 4).density.values, make_smoke(16, 4).density.values);
  for (const auto& m : {make_cloud(32, 0), make_smoke(32, 0), make_blobs(32, 0)}) {
    EXPECT_GE(m.density.min_value(), 0.0f);
    EXPECT_LE(m.density.max_value(), 1.0f);
    EXPECT_GT(m.density.max_value(), 0.5f);
    EXPECT_LT(m.density.at(0, 0, 0), 1e-6f);  // empty at the box corners
  }
  const Grid torus = make_torus_sdf(32, 0);
  EXPECT_LT(torus.min_value(), 0.0f);
  EXPECT_GT(torus.max_value(), 0.0f);
  const Grid spheres = make_spheres_sdf(32, 0);
  EXPECT_LT(spheres.sample(0, 0, -0.15), -0.35);  // deep inside the central sphere (radius 0.45)
}

TEST(Camera, LookAtFollowsOpenGlAxesAndNerfPixelConvention) {
  const Camera c = Camera::look_at({0, -4, 0}, {0, 0, 0}, {0, 0, 1}, 0.8f, 64, 48);
  const Float3 centre = c.direction(32, 24);
  EXPECT_NEAR(centre[1], 1.0, 1e-6);  // looks at the origin (down its -z)
  const Float3 top = c.direction(32, 0);
  EXPECT_GT(top[2], 0.0f);  // the top row looks up (+z world, +y camera)
  const Float3 right = c.direction(64, 24);
  EXPECT_GT(right[0], 0.0f);
  EXPECT_NEAR(std::atan2(right[0], right[1]), 0.4, 1e-5);  // half of camera_angle_x at the right edge
  EXPECT_NEAR(c.transform[2][1], 1.0, 1e-6);               // camera +y is world +z
}

TEST(Environment, PdfIntegratesToOneAndMatchesRadianceDistribution) {
  const EnvironmentLight env = EnvironmentLight::sky(64, 32, 7, 1.0f, false);
  // Midpoint quadrature on a grid 4x finer than the texels.
  const int nt = 128, np = 256;
  double integral = 0;
  for (int a = 0; a < nt; ++a)
    for (int b = 0; b < np; ++b) {
      const double th = (a + 0.5) / nt * kPi, ph = (b + 0.5) / np * 2 * kPi;
      const Float3 d{float(std::sin(th) * std::cos(ph)), float(std::sin(th) * std::sin(ph)), float(std::cos(th))};
      integral += env.pdf(d) * std::sin(th) * (kPi / nt) * (2 * kPi / np);
    }
  EXPECT_NEAR(integral, 1.0, 2e-3);
  EXPECT_THROW(EnvironmentLight(Image(4, 2, 3, 0.0f), 1.0f, false), InvalidArgument);  // black map
  EXPECT_THROW(EnvironmentLight(Image(4, 2, 3, -1.0f), 1.0f, false), InvalidArgument);
}

TEST(Vdb, ImportsTheFogVolumeFixture) {
  const std::string path = std::string(RELIT_TEST_DATA_DIR) + "/sphere_fog.vdb";
  const Grid g = load_vdb_density(path, "", 24, 0.9f);
  EXPECT_EQ(g.nx, 24);
  EXPECT_NEAR(g.max_value(), 1.0f, 1e-6f);
  EXPECT_GT(g.sample(0, 0, 0), 0.9);  // the fixture is a fog sphere centred in its bounding box
  EXPECT_EQ(g.at(0, 0, 0), 0.0f);     // corners are empty
  EXPECT_THROW(load_vdb_density(path, "no_such_grid", 16), IOError);
  Json j = Scene::builtin_json("cloud", 0, 16);
  j["medium"]["source"] = {{"type", "vdb"}, {"file", "sphere_fog.vdb"}, {"resolution", 16}};
  const Scene s = Scene::from_json(j, RELIT_TEST_DATA_DIR);
  const std::string resolved = s.description["medium"]["source"]["file"];
  EXPECT_TRUE(std::filesystem::path(resolved).is_absolute()) << resolved;
  EXPECT_EQ(Scene::from_json(s.description).medium->density.values, s.medium->density.values);
  // A fog volume that relit did not export, given as the scene itself: fitted into the box and normalised.
  const Scene direct = Scene::builtin_or_file(path);
  EXPECT_EQ(direct.description["medium"]["source"]["placement"], "fit");
  EXPECT_EQ(direct.medium->density.values, load_vdb_density(path, "", 64, 0.9f).values);
}

}  // namespace relit
