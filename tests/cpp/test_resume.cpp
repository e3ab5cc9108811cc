// Resuming a run is bit-exact for every method: training N steps straight and training k steps, stopping and
// resuming to N give the same final checkpoint, byte for byte (θ, ψ, density grid, both optimisers' moments,
// step, validation PSNR), and the same logged losses and learning rates. The schedule's intervals are small so
// that the stop at k = 7 of N = 11 falls between events of every kind: density-grid refreshes (every 3 steps:
// the last before the stop at 6, the next after it at 9), validations (every 4: 4 and 8), checkpoints (every 5:
// 5 and 10) and a continuously decaying learning rate (halved every 3 steps). Through the C++ API (also from the
// periodic checkpoint at step 5, as after a crash) and through `relit train --resume`.
#include "test_support.hpp"

#include <relit/dataset.hpp>
#include <relit/io/file.hpp>
#include <relit/method/trainer.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace relit {
namespace {

namespace fs = std::filesystem;

constexpr std::uint64_t kSteps = 11, kStop = 7, kCrash = 5, kValidateEvery = 4;

Json resume_model(const std::string& method) {
  const Json mlp = test::tiny_mlp(), freq = test::tiny_frequency();
  const Json grid = {{"resolution", 8}, {"march_steps", 16}, {"refresh_every", 3}};
  if (method == "bi")
    return {{"renderer", {{"n_samples", 16}, {"n_fine_samples", 16}}},
            {"density_grid", grid},
            {"property", {{"encoding", freq}, {"network", mlp}}},
            {"coarse", {{"encoding", freq}, {"network", mlp}}},
            {"visibility", {{"position_encoding", freq}, {"direction_encoding", freq}, {"network", mlp}}}};
  if (method == "nerv")
    return {
        {"renderer", {{"n_samples", 16}}},
        {"bounce", {{"n_dirs", 8}, {"n_dirs_render", 8}}},
        {"density_grid", grid},
        {"property", {{"encoding", freq}, {"network", mlp}}},
        {"visibility", {{"position_encoding", freq}, {"direction_encoding", freq}, {"trunk", mlp}, {"network", mlp}}}};
  Json m = test::tiny_ours_model("");
  m["density_grid"] = grid;
  return m;
}

Json resume_config(const std::string& method) {
  const Json adam = {{"type", "Adam"}, {"learning_rate", 1e-2}, {"decay_rate", 0.5}, {"decay_steps", 3}};
  return {{"method", method},
          {"model", resume_model(method)},
          {"training",
           {{"batch_rays", 64},
            {"steps", kSteps},
            {"seed", 4},
            {"log_every", 1},
            {"validate_every", kValidateEvery},
            {"validation_views", 1},
            {"checkpoint_every", 5},
            {"optimizer", adam},
            {"visibility_optimizer", adam}}}};
}

std::string file_bytes(const fs::path& p) { return io::read_file(p.string()); }

// log.jsonl by step (a later line of a step replaces an earlier one).
std::map<std::uint64_t, Json> read_log(const fs::path& dir) {
  std::map<std::uint64_t, Json> lines;
  std::ifstream in(dir / "log.jsonl");
  for (std::string line; std::getline(in, line);) {
    const Json j = Json::parse(line);
    lines[j.at("step").get<std::uint64_t>()] = j;
  }
  return lines;
}

// The resumed run's log holds every line of the straight one (and the lines of its stops), with the same losses,
// learning rate and skip count, and the same validation PSNR on the lines of scheduled validations and the last.
void expect_same_log(const fs::path& straight, const fs::path& resumed, const std::vector<std::uint64_t>& stops) {
  const auto a = read_log(straight), b = read_log(resumed);
  ASSERT_EQ(a.size(), kSteps) << "log_every 1: one line per step";
  EXPECT_EQ(b.size(), a.size());
  for (const auto& [step, line] : a) {
    SCOPED_TRACE("log line of step " + std::to_string(step));
    const auto it = b.find(step);
    ASSERT_NE(it, b.end());
    for (const char* key : {"loss", "visibility_loss", "lr", "skipped"})
      EXPECT_EQ(it->second.at(key), line.at(key)) << key;
    // A stop validates too ("the last step"), so its line and the lines after it up to the next scheduled
    // validation report that PSNR, where the straight run reports the one before.
    const bool reports_stop = std::any_of(stops.begin(), stops.end(), [&](std::uint64_t s) {
      return step >= s && step < (s / kValidateEvery + 1) * kValidateEvery;
    });
    if (!reports_stop) {
      EXPECT_EQ(it->second.value("val_psnr", Json()), line.value("val_psnr", Json()));
    }
  }
}

class Resume : public ::testing::TestWithParam<std::string> {
 protected:
  static void SetUpTestSuite() {
    s_dir = new test::TempDir("resume");
    generate_dataset(test::test_device(), Scene::from_json(Scene::builtin_json("cloud", 1, 16)), dataset(),
                     test::tiny_dataset(3, 1));
  }
  static void TearDownTestSuite() {
    delete s_dir;
    s_dir = nullptr;
  }
  static std::string dataset() { return (s_dir->path() / "ds").string(); }
  static test::TempDir* s_dir;
};
test::TempDir* Resume::s_dir = nullptr;

TEST_P(Resume, IsBitExactThroughTheApi) {
  const Device dev = test::test_device();
  const Json config = resume_config(GetParam());
  test::TempDir out("resume-api");
  const fs::path straight = out.path() / "straight", stopped = out.path() / "stopped", crashed = out.path() / "crashed";
  {
    method::Trainer t(dev, dataset(), config);
    t.set_output(straight.string());
    t.run_until(kSteps);
  }
  {
    // Stopped at k (a final checkpoint and an extra validation there); the periodic checkpoint of step 5 is kept
    // as a crash would leave it.
    method::Trainer t(dev, dataset(), config);
    t.set_output(stopped.string());
    t.run_until(kStop, [&](const method::TrainStats& s) {
      if (s.step == kCrash) {
        fs::create_directories(crashed);
        fs::copy_file(stopped / "checkpoint.relit", crashed / "checkpoint.relit");
        fs::copy_file(stopped / "log.jsonl", crashed / "log.jsonl");
      }
      return true;
    });
    EXPECT_EQ(t.steps(), kStop);
  }
  // (The comparison can fail: the checkpoint of the stop is not the final one.)
  EXPECT_FALSE(file_bytes(stopped / "checkpoint.relit") == file_bytes(straight / "checkpoint.relit"));
  for (const auto& [dir, step] : {std::pair{stopped, kStop}, std::pair{crashed, kCrash}}) {
    SCOPED_TRACE("resumed at step " + std::to_string(step));
    method::Trainer t(dev, dataset(), config);
    t.set_output(dir.string());
    t.load_checkpoint((dir / "checkpoint.relit").string());
    EXPECT_EQ(t.steps(), step);
    t.run_until(kSteps);
    EXPECT_TRUE(file_bytes(dir / "checkpoint.relit") == file_bytes(straight / "checkpoint.relit"))
        << "the final checkpoints differ";
    expect_same_log(straight, dir, step == kStop ? std::vector<std::uint64_t>{kStop} : std::vector<std::uint64_t>{});
  }
}

#ifdef RELIT_APP_PATH
// `relit train` for N steps against `relit train --steps k` and `relit train --resume` to N: the same final
// checkpoint, byte for byte, and the same logged losses.
TEST_P(Resume, IsBitExactThroughTheCommandLine) {
  test::TempDir out("resume-cli");
  const fs::path cfg = out.path() / "run.json";
  io::write_file_atomic(cfg.string(), resume_config(GetParam()).dump(2));
  const auto relit = [&](const std::string& args) {
    const std::string cmd = std::string("\"") + RELIT_APP_PATH + "\" train \"" + dataset() + "\" " + args + " > \"" +
                            (out.path() / "output.txt").string() + "\" 2>&1";
    const int rc = std::system(cmd.c_str());
    EXPECT_EQ(rc, 0) << cmd << "\n" << file_bytes(out.path() / "output.txt");
  };
  const fs::path straight = out.path() / "straight", resumed = out.path() / "resumed";
  relit("--config \"" + cfg.string() + "\" --out \"" + straight.string() + "\"");
  relit("--config \"" + cfg.string() + "\" --out \"" + resumed.string() + "\" --steps " + std::to_string(kStop));
  ASSERT_TRUE(fs::exists(resumed / "checkpoint.relit"));
  EXPECT_FALSE(file_bytes(resumed / "checkpoint.relit") == file_bytes(straight / "checkpoint.relit"));
  relit("--out \"" + resumed.string() + "\" --resume");  // to the config's training.steps
  EXPECT_TRUE(file_bytes(resumed / "checkpoint.relit") == file_bytes(straight / "checkpoint.relit"))
      << "the final checkpoints differ";
  expect_same_log(straight, resumed, {kStop});
}
#endif

INSTANTIATE_TEST_SUITE_P(Methods, Resume, ::testing::Values("ours", "ours_brdf", "bi", "nerv"),
                         [](const auto& info) { return info.param; });

}  // namespace
}  // namespace relit
