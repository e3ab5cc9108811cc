// Dataset generation: protocol planning, a round trip (cameras, lights, pixels), atomicity and bad input.
#include "test_support.hpp"

#include <relit/dataset.hpp>
#include <relit/io/file.hpp>
#include <relit/io/image.hpp>

#include <cmath>
#include <functional>
#include <fstream>

namespace relit {

namespace fs = std::filesystem;

namespace {
DatasetSettings tiny() {
  DatasetSettings s;
  s.resolution = 8;
  s.train = 3;
  s.val = 1;
  s.test = 2;
  s.spp = 2;
  s.seed = 5;
  return s;
}
Scene tiny_scene() { return Scene::from_json(Scene::builtin_json("cloud", 1, 16)); }
double norm(const Float3& v) { return std::sqrt(double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2]); }
}  // namespace

TEST(Dataset, PlanFollowsTheLightingProtocols) {
  DatasetSettings s;
  s.train = 100;
  s.intensity_min = 50;
  s.intensity_max = 900;
  s.generalization = true;
  const DatasetDescription d = plan_dataset(s);
  ASSERT_EQ(d.splits.at("train").size(), 100u);
  ASSERT_EQ(d.splits.at("val").size(), 20u);
  ASSERT_EQ(d.splits.at("test").size(), 50u);
  double lo = 1e9, hi = 0;
  for (const auto& f : d.splits.at("train")) {
    const double dist = norm(f.light.position);
    EXPECT_GE(dist, 3.0 - 1e-5);
    EXPECT_LE(dist, 5.0 + 1e-5);
    EXPECT_NEAR(norm(f.camera.position()), 4.0, 1e-4);
    EXPECT_GE(f.light.intensity[0], 50.0f);
    EXPECT_LE(f.light.intensity[0], 900.0f);
    lo = std::min(lo, double(f.light.intensity[0])), hi = std::max(hi, double(f.light.intensity[0]));
    // Every camera looks at the centre.
    const Float3 c = f.camera.direction(f.camera.width / 2.0, f.camera.height / 2.0), p = f.camera.position();
    EXPECT_NEAR(c[0] * p[0] + c[1] * p[1] + c[2] * p[2], -norm(p), 1e-3);
  }
  EXPECT_LT(lo, 80);  // stratified over the range
  EXPECT_GT(hi, 870);
  for (int dist : {3, 5, 7, 10})
    for (const auto& f : d.splits.at("test_distance_" + std::to_string(dist)))
      EXPECT_NEAR(norm(f.light.position), dist, 1e-4);
  for (int inten : {400, 800, 1200, 1600})
    for (const auto& f : d.splits.at("test_intensity_" + std::to_string(inten))) {
      EXPECT_EQ(f.light.intensity[1], float(inten));
      EXPECT_NEAR(norm(f.light.position), 4.0, 1e-4);
    }
  // The sets scale with generalization_intensity: 2/3, 4/3, 2 and 8/3 of it.
  EXPECT_EQ(generalization_intensities(600), (std::vector<int>{400, 800, 1200, 1600}));
  EXPECT_EQ(generalization_intensities(80), (std::vector<int>{53, 107, 160, 213}));
  // Novel test cameras: none coincides with a training camera.
  for (const auto& t : d.splits.at("test"))
    for (const auto& f : d.splits.at("train")) EXPECT_NE(t.camera.transform, f.camera.transform);
  // Same seed, same plan.
  EXPECT_EQ(plan_dataset(s).splits.at("val")[3].light.position, d.splits.at("val")[3].light.position);
}

TEST(Dataset, RoundTripGivesIdenticalCamerasLightsAndPixels) {
  test::TempDir dir("dataset");
  const Device dev = test::test_device();
  const Scene scene = tiny_scene();
  DatasetSettings s = tiny();
  s.test_spp = 5;  // cleaner test references than the training images
  const std::string out = (dir.path() / "ds").string();
  generate_dataset(dev, scene, out, s);
  const DatasetDescription plan = plan_dataset(s), back = read_dataset(out);
  EXPECT_EQ(back.lighting, "point");
  EXPECT_EQ(Json::parse(io::read_file(out + "/transforms_test.json"))["spp"], 5);
  EXPECT_EQ(Json::parse(io::read_file(out + "/transforms_train.json"))["spp"], s.spp);
  EXPECT_TRUE(back.environment.is_null());
  ASSERT_EQ(back.splits.size(), 3u);
  const PathTracer pt(dev, scene);
  for (const auto& [name, frames] : plan.splits) {
    ASSERT_EQ(back.splits.at(name).size(), frames.size()) << name;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      const DatasetFrame& a = frames[i];
      const DatasetFrame& b = back.splits.at(name)[i];
      EXPECT_EQ(a.file_path, b.file_path);
      EXPECT_EQ(a.camera.transform, b.camera.transform);
      EXPECT_EQ(a.camera.camera_angle_x, b.camera.camera_angle_x);
      EXPECT_EQ(a.camera.width, b.camera.width);
      EXPECT_EQ(a.light.position, b.light.position);
      EXPECT_EQ(a.light.intensity, b.light.intensity);
      const Image img = read_image((fs::path(out) / b.file_path).string());
      ASSERT_EQ(img.channels, 4);
      EXPECT_TRUE(fs::exists(fs::path(out) / (name + "/r_00" + std::to_string(i) + ".png")));
      if (i == 0) {  // stored pixels are exactly the render of that view (float EXR: bit exact)
        PathTraceSettings rs;
        rs.spp = name == "test" ? s.test_spp : s.spp;
        rs.seed = dataset_view_seed(s.seed, name, i);
        EXPECT_EQ(img.pixels, pt.render(a.camera, {a.light}, rs).image.pixels) << name;
      }
    }
  }
  const Image stored = read_image((fs::path(out) / "train/r_000.exr").string());
  double sum = 0;
  for (std::size_t p = 0; p < stored.pixels.size(); p += 4) sum += stored.pixels[p];
  EXPECT_GT(sum, 0.0) << "a lit cloud must not render black";
  EXPECT_TRUE(fs::exists(fs::path(out) / "scene.json"));
  const Scene reloaded = Scene::load((fs::path(out) / "scene.json").string());
  EXPECT_EQ(reloaded.medium->density.values, scene.medium->density.values);
  // Nothing but the dataset is left in the parent folder (no temporary folders).
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir.path())) entries += 1, (void)e;
  EXPECT_EQ(entries, 1);
}

TEST(Dataset, LoadSplitReadsTheViewsBackAndNamesWhatIsWrong) {
  test::TempDir dir("dataset");
  DatasetSettings s = tiny();
  s.train = 4;
  const std::string out = (dir.path() / "ds").string();
  generate_dataset(test::test_device(), tiny_scene(), out, s);
  const DatasetDescription desc = read_dataset(out);
  const DatasetSplit train = load_split(out, "train");
  ASSERT_EQ(train.size(), 4u);
  EXPECT_EQ(train.split, "train");
  EXPECT_EQ(train.width, s.resolution);
  EXPECT_EQ(train.height, s.resolution);
  EXPECT_EQ(train.environment, nullptr);
  ASSERT_EQ(train.images.size(), 4u * s.resolution * s.resolution * 3);
  for (std::size_t i = 0; i < train.size(); ++i) {
    const DatasetFrame& f = desc.splits.at("train")[i];
    EXPECT_EQ(train.names[i], fs::path(f.file_path).stem().string());
    EXPECT_EQ(train.cameras[i].transform, f.camera.transform);
    EXPECT_EQ(train.lights[i].position, f.light.position);
    // The RGB of the stored RGBA image, bit for bit.
    const Image img = read_image((fs::path(out) / f.file_path).string());
    const std::vector<float> rgb = train.image(i);
    ASSERT_EQ(rgb.size(), std::size_t(s.resolution) * s.resolution * 3);
    for (std::size_t p = 0; p < rgb.size() / 3; ++p)
      for (int c = 0; c < 3; ++c) ASSERT_EQ(rgb[p * 3 + c], img.pixels[p * 4 + c]) << i << " " << p;
  }
  // max_views keeps views spread evenly over the split: 0 and 2 of 4.
  const DatasetSplit two = load_split(out, "train", 2);
  ASSERT_EQ(two.size(), 2u);
  EXPECT_EQ(two.names[0], train.names[0]);
  EXPECT_EQ(two.names[1], train.names[2]);
  // A missing split names the splits there are; a non-finite pixel names its file.
  try {
    load_split(out, "test_distance_3");
    FAIL() << "a missing split must throw";
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find("splits: test, train, val"), std::string::npos) << e.what();
  }
  const fs::path view = fs::path(out) / desc.splits.at("val")[0].file_path;
  Image bad = read_image(view.string());
  bad.pixels[5] = std::nanf("");
  write_image(view.string(), bad);
  try {
    load_split(out, "val");
    FAIL() << "a NaN pixel must throw";
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find(view.filename().string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("NaN"), std::string::npos) << e.what();
  }
}

TEST(Dataset, EnvPlusPointWritesTheEnvironmentMap) {
  test::TempDir dir("dataset");
  DatasetSettings s = tiny();
  s.lighting = "env+point";
  s.train = 1, s.val = 0, s.test = 0;
  const std::string out = (dir.path() / "ds").string();
  generate_dataset(test::test_device(), tiny_scene(), out, s);
  const DatasetDescription back = read_dataset(out);
  ASSERT_TRUE(back.environment.is_object());
  EXPECT_EQ(back.environment["file"], "environment.exr");
  EXPECT_GT(read_image((fs::path(out) / "environment.exr").string()).width, 0);
  const Scene reloaded = Scene::load((fs::path(out) / "scene.json").string());
  EXPECT_TRUE(reloaded.environment.has_value());
}

TEST(Dataset, ExistingFoldersAreNotDamagedAndCancelledRunsLeaveNothing) {
  test::TempDir dir("dataset");
  const Device dev = test::test_device();
  const fs::path out = dir.path() / "ds";
  fs::create_directories(out);
  std::ofstream(out / "keep.txt") << "precious";
  EXPECT_THROW(generate_dataset(dev, tiny_scene(), out.string(), tiny()), IOError);
  EXPECT_TRUE(fs::exists(out / "keep.txt"));

  const fs::path out2 = dir.path() / "ds2";
  int calls = 0;
  EXPECT_THROW(generate_dataset(dev, tiny_scene(), out2.string(), tiny(), [&](const Progress&) { return ++calls < 3; }),
               Cancelled);
  EXPECT_FALSE(fs::exists(out2));
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir.path())) entries += 1, (void)e;
  EXPECT_EQ(entries, 1) << "a cancelled generation must leave no temporary folder";

  // --overwrite replaces only a dataset relit wrote: never a folder of other files, nor a file.
  DatasetSettings s = tiny();
  s.overwrite = true;
  const auto folder_before = test::snapshot(out);
  EXPECT_THROW(generate_dataset(dev, tiny_scene(), out.string(), s), IOError);
  EXPECT_EQ(test::snapshot(out), folder_before);
  const fs::path file = dir.path() / "notes.txt";
  std::ofstream(file) << "precious";
  EXPECT_THROW(generate_dataset(dev, tiny_scene(), file.string(), s), IOError);
  EXPECT_EQ(io::read_file(file.string()), "precious");
  fs::remove(file);

  // A relit dataset is replaced, only by a complete one.
  const fs::path ds = dir.path() / "ds3";
  generate_dataset(dev, tiny_scene(), ds.string(), tiny());
  const auto old = test::snapshot(ds);
  const auto parent_before = test::snapshot(dir.path());
  {
    test::FailWrites fail(io::testing::Stage::rename, "ds3");  // the new dataset fails to move into place
    EXPECT_THROW(generate_dataset(dev, tiny_scene(), ds.string(), s), IOError);
  }
  EXPECT_EQ(test::snapshot(dir.path()), parent_before) << "the old dataset changed or a temporary was left";
  s.seed = 6;
  generate_dataset(dev, tiny_scene(), ds.string(), s);
  EXPECT_NE(test::snapshot(ds), old);
  EXPECT_TRUE(fs::exists(ds / "transforms_train.json"));
  // ... but not once the user has added files of their own.
  std::ofstream(ds / "train" / "my_notes.txt") << "mine";
  EXPECT_THROW(generate_dataset(dev, tiny_scene(), ds.string(), s), IOError);
  EXPECT_EQ(io::read_file((ds / "train" / "my_notes.txt").string()), "mine");

  DatasetSettings bad = tiny();
  bad.intensity_min = -1;
  EXPECT_THROW(generate_dataset(dev, tiny_scene(), (dir.path() / "x").string(), bad), InvalidArgument);
  bad = tiny();
  bad.lighting = "sun";
  EXPECT_THROW(plan_dataset(bad), InvalidArgument);
  EXPECT_THROW(read_dataset((dir.path() / "nothing").string()), IOError);
}

// Hand-edited or foreign transforms files: each defect is an IOError naming the file, the frame and the key.
TEST(Dataset, MalformedTransformsAreClearErrorsNamingTheFrameAndKey) {
  test::TempDir dir("dataset-bad");
  const std::string out = (dir.path() / "ds").string();
  generate_dataset(test::test_device(), tiny_scene(), out, tiny());
  const std::string path = (fs::path(out) / "transforms_train.json").string();
  const Json good = parse_json(io::read_file(path), path);
  const std::vector<std::pair<std::function<void(Json&)>, std::string>> cases = {
      {[](Json& d) { d["frames"][1].erase("light"); }, "frames[1] (train/r_001.exr).light is missing"},
      {[](Json& d) { d["frames"][0]["light"]["type"] = "spot"; }, "light.type must be \"point\""},
      {[](Json& d) { d["frames"][0]["light"]["colour"] = 1; }, "light.colour is not a key"},
      {[](Json& d) {
         d["frames"][0]["light"]["position"] = {0.2, 0, 0};
       },
       "inside the scene box"},
      {[](Json& d) {
         d["frames"][0]["light"]["position"] = {1e30, 0, 0};
       },
       "within 1e6"},
      {[](Json& d) {
         d["frames"][0]["light"]["intensity"] = {1, 2};
       },
       "light.intensity must be an array of 3"},
      {[](Json& d) { d["lighting"] = "sun"; }, "lighting must be \"point\" or \"env+point\""},
      {[](Json& d) { d.erase("lighting"); }, "lighting must be"},
      {[](Json& d) { d["w"] = 0; }, "w must be the image width"},
      {[](Json& d) { d["camera_angle_x"] = "wide"; }, "camera_angle_x must be a finite number"},
      {[](Json& d) { d["frames"][0]["file_path"] = "../../etc/passwd"; }, "leaves the dataset folder"},
      {[](Json& d) { d["frames"][0]["file_path"] = "/etc/passwd"; }, "leaves the dataset folder"},
      {[](Json& d) {
         for (auto& row : d["frames"][0]["transform_matrix"]) row = {0, 0, 0, 0};
       },
       "bottom row"},
      {[](Json& d) {
         for (int r = 0; r < 3; ++r) d["frames"][0]["transform_matrix"][r] = {0, 0, 0, 1};
       },
       "must be a rotation"},
      {[](Json& d) {
         d["frames"][0]["transform_matrix"][3] = {0, 0, 0, 2};
       },
       "bottom row"},
      {[](Json& d) {
         d["frames"][0]["transform_matrix"] = {1, 2, 3};
       },
       "must be a 4x4 array"},
      {[](Json& d) {
         d["environment"] = {{"file", "environment.exr"}};
       },
       "must be null for lighting \"point\""},
      {[](Json& d) { d["frames"] = 3; }, "frames must be an array"},
  };
  for (const auto& [edit, expected] : cases) {
    Json doc = good;
    edit(doc);
    io::write_file_atomic(path, doc.dump(2));
    std::string m = "(no error)";
    try {
      read_dataset(out);
    } catch (const IOError& e) {
      m = e.what();
    }
    EXPECT_NE(m.find(expected), std::string::npos) << "expected '" << expected << "', got: " << m;
    EXPECT_NE(m.find("transforms_train.json"), std::string::npos) << m;
  }
  // A duplicate key is ambiguous: refused too.
  std::string text = good.dump();
  text.insert(1, "\"w\": 4, ");
  io::write_file_atomic(path, text);
  EXPECT_THROW(read_dataset(out), Error);
  io::write_file_atomic(path, good.dump(2));
  EXPECT_NO_THROW(read_dataset(out));

  // Splits must agree on the lighting and the environment, whatever order the folder lists them in.
  const std::string val = (fs::path(out) / "transforms_val.json").string();
  const std::string val_text = io::read_file(val);
  Json v = parse_json(val_text, val);
  v["lighting"] = "env+point";
  v["environment"] = {{"file", "environment.exr"}, {"scale", 1}, {"visible", false}};
  io::write_file_atomic(val, v.dump(2));
  EXPECT_THROW(read_dataset(out), IOError);
  io::write_file_atomic(val, val_text);

  // Negative radiance is not data.
  const fs::path view = fs::path(out) / read_dataset(out).splits.at("val")[0].file_path;
  Image img = read_image(view.string());
  img.pixels[3 * img.channels + 1] = -0.5f;
  write_image(view.string(), img);
  try {
    load_split(out, "val");
    FAIL() << "a negative pixel must throw";
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find("pixel (3, 0) channel 1"), std::string::npos) << e.what();
  }
}

}  // namespace relit
