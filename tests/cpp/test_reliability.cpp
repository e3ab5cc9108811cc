// Bad input and failing disks: every atomic writer keeps the old bytes and leaves no temporary when its write or
// rename fails; the temporaries of killed runs are recognised and removed; strict JSON; cameras and lights that
// cannot be rendered are refused where they enter.
#include "test_support.hpp"

#include <relit/io/checkpoint.hpp>
#include <relit/io/file.hpp>
#include <relit/io/image.hpp>

#include <gtest/gtest.h>

#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>

namespace relit {
namespace {

namespace fs = std::filesystem;
using io::testing::Stage;

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(AtomicWrite, AFailedWriteOrRenameKeepsTheOldBytesAndLeavesNoTemporary) {
  test::TempDir dir("atomic");
  const std::string json = (dir.path() / "a.json").string(), exr = (dir.path() / "a.exr").string(),
                    png = (dir.path() / "a.png").string(), ckpt = (dir.path() / "a.relit").string();
  io::write_file_atomic(json, "old");
  write_image(exr, Image(3, 2, 3, 0.25f));
  write_image(png, Image(3, 2, 4, 0.5f));
  io::Checkpoint c;
  c.tensors["w"] = {1, 2, 3};
  io::save_checkpoint(ckpt, c);
  const auto before = test::snapshot(dir.path());
  io::Checkpoint c2;
  c2.tensors["w"] = {4, 5, 6, 7};
  for (Stage stage : {Stage::write, Stage::rename}) {
    test::FailWrites fail(stage);
    EXPECT_THROW(io::write_file_atomic(json, "new"), IOError);
    EXPECT_THROW(io::save_checkpoint(ckpt, c2), IOError);
    if (stage == Stage::rename) {  // images are written by OpenImageIO, then checked and renamed
      EXPECT_THROW(write_image(exr, Image(3, 2, 3, 9.0f)), IOError);
      EXPECT_THROW(write_image(png, Image(3, 2, 4, 0.9f)), IOError);
    }
    EXPECT_EQ(test::snapshot(dir.path()), before) << "old bytes changed or a temporary was left behind";
  }
  // The message names the file.
  test::FailWrites fail(Stage::rename);
  EXPECT_NE(message_of([&] { io::write_file_atomic(json, "x"); }).find("a.json"), std::string::npos);
}

TEST(AtomicWrite, WithoutFailuresTheNewBytesArrive) {
  test::TempDir dir("atomic-ok");
  const std::string json = (dir.path() / "a.json").string();
  io::write_file_atomic(json, "old");
  io::write_file_atomic(json, "new");
  EXPECT_EQ(io::read_file(json), "new");
  io::write_file_atomic(json, "");  // an empty file asked for is written
  EXPECT_EQ(io::read_file(json), "");
  EXPECT_EQ(test::snapshot(dir.path()).size(), 1u);
}

TEST(AtomicWrite, StaleTemporariesOfDeadProcessesAreRemovedAndNothingElse) {
  test::TempDir dir("stale");
  const std::string dead = "99999999";  // above any pid_max: no such process
  const std::string mine = std::to_string(::getpid());
  for (const std::string& name : {".checkpoint.tmp-" + dead + "-0.relit", ".metrics.tmp-" + dead + "-3.json"})
    std::ofstream(dir.path() / name) << "partial";
  fs::create_directories(dir.path() / (".ds.partial-" + dead) / "train");
  std::ofstream(dir.path() / (".ds.partial-" + dead) / "train" / "r_000.exr") << "partial";
  // Kept: what a live process is writing, and anything that only looks similar.
  const std::vector<std::string> kept = {".checkpoint.tmp-" + mine + "-0.relit", ".notes.tmp-backup", "notes.txt",
                                         ".ds.partial-abc", "checkpoint.tmp-" + dead + "-0.relit"};
  for (const auto& name : kept) std::ofstream(dir.path() / name) << "keep";
  EXPECT_EQ(io::remove_stale_temporaries(dir.path().string()), 3);
  std::vector<std::string> left;
  for (const auto& e : fs::directory_iterator(dir.path())) left.push_back(e.path().filename().string());
  std::sort(left.begin(), left.end());
  std::vector<std::string> want = kept;
  std::sort(want.begin(), want.end());
  EXPECT_EQ(left, want);
  EXPECT_EQ(io::temporary_owner(".a.tmp-123-4.exr"), 123);
  EXPECT_EQ(io::temporary_owner(".a.partial-77"), 77);
  EXPECT_EQ(io::temporary_owner("a.txt"), 0);
}

TEST(AtomicWrite, FoldersThatCannotHoldOutputAreClearErrors) {
  test::TempDir dir("dirs");
  const std::string file = (dir.path() / "file").string();
  io::write_file_atomic(file, "x");
  EXPECT_NE(message_of([&] { io::create_directories(file, "run folder"); }).find("is an existing file"),
            std::string::npos);
  EXPECT_NE(message_of([&] { io::create_directories(file + "/sub", "run folder"); }).find("cannot create"),
            std::string::npos);
  EXPECT_NE(message_of([&] {
              io::create_directories((dir.path() / std::string(300, 'a')).string(), "run folder");
            }).find("cannot create"),
            std::string::npos);
  EXPECT_EQ(io::read_file(file), "x");
  EXPECT_THROW(io::read_file(dir.path().string()), IOError);  // a folder is not a file
}

TEST(StrictJson, DuplicateKeysHugeNumbersAndTypeAliasesAreRefused) {
  EXPECT_NE(message_of([] { parse_json(R"({"a": 1, "b": {"c": 1, "c": 2}})", "f.json"); }).find("\"c\" appears twice"),
            std::string::npos);
  EXPECT_NE(message_of([] { parse_json(R"({"a": 1, "b": {"c": 1, "c": 2}})", "f.json"); }).find("'/b'"),
            std::string::npos);
  EXPECT_NE(message_of([] { parse_json(R"({"a": 1, "a": 1})", "f.json"); }).find("f.json"), std::string::npos);
  EXPECT_NE(message_of([] { parse_json(R"({"a": 1e999})", "f.json"); }).find("outside the range"), std::string::npos);
  EXPECT_NE(message_of([] { parse_json(R"({"a": )", "f.json"); }).find("not valid JSON"), std::string::npos);
  // The same key in sibling objects is fine.
  EXPECT_EQ(parse_json(R"({"x": {"k": 1}, "y": {"k": 2}, "z": [{"k": 1}, {"k": 2}]})", "f")["y"]["k"], 2);
  EXPECT_NE(message_of([] { parse_json(R"([{"k": 1, "k": 2}])", "f"); }).find("appears twice"), std::string::npos);
  EXPECT_THROW(config::component_type({{"type", "HashGrid"}, {"otype", "Frequency"}}, "/enc", ""), ConfigError);
  // A section given as anything but an object is refused at its pointer (null only where null is the default).
  for (const Json& bad : {Json::array(), Json("x"), Json(), Json(3)}) {
    config::Reader r(Json{{"model", bad}}, "", "run");
    EXPECT_NE(message_of([&] {
                r.sub("model", Json::object(), "object", "the model");
              }).find("/model: must be a JSON object"),
              std::string::npos)
        << bad.dump();
  }
  config::Reader none(Json{{"medium", nullptr}}, "", "scene");
  EXPECT_TRUE(none.sub("medium", Json(), "object", "a medium").is_null());
  EXPECT_EQ(config::component_type({{"type", "HashGrid"}, {"otype", "HashGrid"}}, "/enc", ""), "HashGrid");
}

TEST(Camera, DegenerateCamerasAreRefusedWhereTheyEnter) {
  EXPECT_NE(message_of([] {
              Camera::look_at({1, 2, 3}, {1, 2, 3}, {0, 0, 1}, 0.8f, 8, 8);
            }).find("same point"),
            std::string::npos);
  Camera c = Camera::look_at({0, -4, 0}, {0, 0, 0}, {0, 0, 1}, 0.8f, 8, 8);
  EXPECT_NO_THROW(c.validate());
  Camera zero = c;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) zero.transform[r][k] = 0;
  EXPECT_NE(message_of([&] { zero.validate(); }).find("rotation"), std::string::npos);
  Camera scaled = c;
  for (int r = 0; r < 3; ++r) scaled.transform[r][0] *= 2;
  EXPECT_THROW(scaled.validate(), InvalidArgument);
  Camera bottom = c;
  bottom.transform[3] = {0, 0, 1, 1};
  EXPECT_NE(message_of([&] { bottom.validate(); }).find("bottom row"), std::string::npos);
}

TEST(Light, LightsInsideTheBoxOrAbsurdlyFarAreRefused) {
  EXPECT_NO_THROW((PointLight{{0, -3, 3}, {600, 600, 600}}.validate()));
  EXPECT_NE(message_of([] {
              PointLight{{0.5f, 0, 0}, {600, 600, 600}}.validate();
            }).find("inside the scene box"),
            std::string::npos);
  EXPECT_THROW((PointLight{{1e30f, 0, 0}, {600, 600, 600}}.validate()), InvalidArgument);
  EXPECT_THROW((PointLight{{0, 0, 4}, {-1, 0, 0}}.validate()), InvalidArgument);
  // In a scene file the error names the light.
  Json scene = Scene::builtin_json("cloud", 1, 8);
  scene["lights"] = Json::array({{{"type", "point"}, {"position", {0.1, 0, 0}}}});
  EXPECT_NE(message_of([&] { Scene::from_json(scene); }).find("/lights/0"), std::string::npos);
}

// A checkpoint whose checksum is right but whose header lies: refused with IOError, never a crash.
std::string forged_checkpoint(const std::string& header) {
  std::string out("RELITCKP", 8);
  auto put = [&](std::uint64_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) out.push_back(char((v >> (8 * i)) & 0xff));
  };
  put(1, 4);
  put(header.size(), 8);
  out += header;
  out.append(16, '\0');  // four floats of tensor data
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char ch : out) h = (h ^ ch) * 1099511628211ull;
  put(h, 8);
  return out;
}

TEST(Checkpoint, ForgedHeadersWithAValidChecksumAreClearErrors) {
  test::TempDir dir("forged");
  io::Checkpoint c;
  c.tensors["w"] = {1, 2, 3, 4};
  const std::string real = (dir.path() / "real.relit").string();
  io::save_checkpoint(real, c);
  const std::string version = io::read_file(real).substr(8, 4);
  ASSERT_EQ(version, std::string("\1\0\0\0", 4)) << "update forged_checkpoint() for the new format version";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"tensors": [{"name": "w", "count": 4611686018427387904, "offset": 0}]})", "outside the file"},
      {R"({"tensors": [{"name": 7, "count": 4, "offset": 0}]})", "lacks a string 'name'"},
      {R"({"tensors": [{"name": "w", "count": -1, "offset": 0}]})", "non-negative integer"},
      {R"({"tensors": [{"name": "w", "count": 1, "offset": 18446744073709551615}]})", "outside the file"},
      {R"({"tensors": [{"name": "w", "count": 1, "offset": 0}, {"name": "w", "count": 1, "offset": 4}]})", "twice"},
      {R"({"tensors": [7]})", "lacks"},
      {R"({"tensors": {}})", "no tensor table"},
      {R"({"tensors": [], "tensors": []})", "appears twice"},
      {R"({"a": 1e999, "tensors": []})", "outside the range"},
  };
  for (const auto& [header, expected] : cases) {
    const std::string path = (dir.path() / "forged.relit").string();
    io::write_file_atomic(path, forged_checkpoint(header));
    const std::string m = message_of([&] { io::load_checkpoint(path); });
    EXPECT_NE(m.find(expected), std::string::npos) << header << " gave: " << m;
  }
}

}  // namespace
}  // namespace relit
