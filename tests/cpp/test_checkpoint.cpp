// Checkpoints: round trip, atomic replacement, and clear errors for truncated, corrupt or foreign files.
#include "test_support.hpp"

#include <relit/io/checkpoint.hpp>
#include <relit/io/file.hpp>

#include <filesystem>

namespace relit {

namespace {
io::Checkpoint sample() {
  io::Checkpoint ck;
  ck.header = {{"step", 1234}, {"config", {{"network", {{"type", "FullyFusedMLP"}}}}}, {"rng", "abc"}};
  ck.tensors["params"] = {1.0f, -2.5f, 3.25f, std::numeric_limits<float>::denorm_min()};
  ck.tensors["adam.m"] = std::vector<float>(1000, 0.125f);
  ck.tensors["empty"] = {};
  return ck;
}
}  // namespace

TEST(Checkpoint, RoundTripIsExact) {
  test::TempDir dir("ckpt");
  const auto path = (dir.path() / "a.relit").string();
  io::save_checkpoint(path, sample());
  const auto back = io::load_checkpoint(path);
  EXPECT_EQ(back.tensors, sample().tensors);
  EXPECT_EQ(back.header["step"], 1234);
  EXPECT_EQ(back.header["config"]["network"]["type"], "FullyFusedMLP");
  EXPECT_EQ(back.header["format_version"], io::kCheckpointVersion);
  EXPECT_EQ(back.header["library_version"], relit::version());
  // No temporary files are left next to it.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), {}), 1);
}

TEST(Checkpoint, TruncatedCorruptAndForeignFilesAreClearErrors) {
  test::TempDir dir("ckpt-bad");
  const auto path = (dir.path() / "a.relit").string();
  io::save_checkpoint(path, sample());
  const std::string good = io::read_file(path);
  auto error_for = [&](const std::string& bytes) -> std::string {
    const auto p = (dir.path() / "b.relit").string();
    io::write_file_atomic(p, bytes);
    try {
      io::load_checkpoint(p);
    } catch (const IOError& e) {
      return e.what();
    }
    return "loaded";
  };
  EXPECT_NE(error_for(good.substr(0, good.size() / 2)).find("checksum mismatch"), std::string::npos);
  std::string flipped = good;
  flipped[good.size() / 2] ^= 0x40;
  EXPECT_NE(error_for(flipped).find("checksum mismatch: the file is truncated or corrupt"), std::string::npos);
  EXPECT_NE(error_for("PK\x03\x04 not a checkpoint at all, but long enough").find("not a relit checkpoint"),
            std::string::npos);
  std::string future = good;
  future[8] = 9;  // format version 9
  EXPECT_NE(error_for(future).find("format version 9"), std::string::npos);
  // Forged headers with a right checksum: Checkpoint.ForgedHeadersWithAValidChecksumAreClearErrors.
  try {
    io::load_checkpoint((dir.path() / "missing.relit").string());
    FAIL();
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.relit"), std::string::npos);
  }
}

TEST(Checkpoint, FailedWriteLeavesTheOldFileIntact) {
  test::TempDir dir("ckpt-keep");
  const auto path = (dir.path() / "a.relit").string();
  io::save_checkpoint(path, sample());
  const auto before = test::snapshot(dir.path());
  io::Checkpoint other = sample();
  other.header["step"] = 99;
  // The same file fails to be replaced after its temporary exists (a full disk, a failed rename): the old
  // bytes stay and no temporary is left.
  for (auto stage : {io::testing::Stage::write, io::testing::Stage::rename}) {
    test::FailWrites fail(stage);
    EXPECT_THROW(io::save_checkpoint(path, other), IOError);
    EXPECT_EQ(test::snapshot(dir.path()), before);
  }
  io::save_checkpoint(path, other);  // and without a failure it is replaced
  EXPECT_EQ(io::load_checkpoint(path).header["step"], 99);
}

}  // namespace relit
