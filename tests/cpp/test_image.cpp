// Image I/O: EXR float round trip, PNG sRGB encoding, atomic writes, clear errors for bad files.
#include "test_support.hpp"

#include <relit/io/file.hpp>
#include <relit/io/image.hpp>
#include <relit/progress.hpp>

#include <filesystem>
#include <fstream>
#include <random>

namespace relit {

namespace fs = std::filesystem;

TEST(Image, ExrRoundTripIsBitExact) {
  test::TempDir dir("image");
  Image img(7, 5, 4);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 50.0f);
  for (auto& v : img.pixels) v = u(rng);
  const std::string path = (dir.path() / "a.exr").string();
  write_image(path, img);
  const Image back = read_image(path);
  ASSERT_EQ(back.width, 7);
  ASSERT_EQ(back.height, 5);
  ASSERT_EQ(back.channels, 4);
  EXPECT_EQ(back.pixels, img.pixels);
  // No temporary files are left next to it.
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir.path())) files += e.is_regular_file();
  EXPECT_EQ(files, 1);
}

TEST(Image, PngIsSrgbEncodedAndDecodesBackToLinear) {
  test::TempDir dir("image");
  Image img(16, 1, 3);
  for (int x = 0; x < 16; ++x)
    for (int c = 0; c < 3; ++c) img.at(x, 0, c) = x / 15.0f;
  img.at(15, 0, 0) = 7.0f;  // clamped
  const std::string path = (dir.path() / "a.png").string();
  write_image(path, img);
  const Image back = read_image(path);
  ASSERT_EQ(back.channels, 3);
  for (int x = 0; x < 15; ++x) {
    // 8-bit sRGB quantisation: half a code step in the encoded domain.
    const float expected = srgb_to_linear(std::round(linear_to_srgb(x / 15.0f) * 255.0f) / 255.0f);
    EXPECT_NEAR(back.at(x, 0, 1), expected, 1e-5f) << x;
  }
  EXPECT_NEAR(back.at(15, 0, 0), 1.0f, 1e-6f);
  EXPECT_NEAR(linear_to_srgb(0.5f), 0.7353569f, 1e-5f);  // the sRGB curve, not a gamma 2.2 approximation
}

TEST(Image, BadFilesGiveClearErrors) {
  test::TempDir dir("image");
  EXPECT_THROW(read_image((dir.path() / "missing.exr").string()), IOError);
  const std::string corrupt = (dir.path() / "corrupt.exr").string();
  std::ofstream(corrupt) << "this is not an EXR file";
  try {
    read_image(corrupt);
    FAIL() << "no error for a corrupt EXR";
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find("corrupt.exr"), std::string::npos) << e.what();
  }
  try {
    read_image(dir.path().string());  // a folder
    FAIL() << "no error for a folder";
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
  }
  EXPECT_THROW(write_image((dir.path() / "a.bmpx").string(), Image(2, 2, 3)), InvalidArgument);
  EXPECT_THROW(write_image((dir.path() / "a.exr").string(), Image()), InvalidArgument);
  EXPECT_THROW(write_image((dir.path() / "no/such/folder/a.exr").string(), Image(2, 2, 3)), IOError);
}

// OpenEXR allocates its line buffers when it opens a file, at the size of the data window: a forged window is
// refused before OpenEXR sees the file (a 212-byte file claiming one row of 6.3 million pixels made it
// allocate and clear 150 MB), with the sizes named.
TEST(Image, ExrDataWindowBeyondTheLimitsIsRefusedBeforeOpenExrAllocates) {
  test::TempDir dir("image");
  const std::string path = (dir.path() / "wide.exr").string();
  write_image(path, Image(7, 5, 3));
  std::string bytes = io::read_file(path);
  const std::string key("dataWindow\0box2i\0", 17);
  const std::size_t at = bytes.find(key);
  ASSERT_NE(at, std::string::npos);
  const auto set_int32 = [&](std::size_t i, std::int32_t v) {
    for (int b = 0; b < 4; ++b) bytes[at + key.size() + 4 + 4 * i + b] = char((std::uint32_t(v) >> (8 * b)) & 0xff);
  };
  set_int32(2, 6291455);  // xmax: one row of 6291456 pixels
  io::write_file_atomic(path, bytes);
  try {
    read_image(path);
    FAIL() << "no error for a data window of 6291456 x 5 pixels";
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find("wide.exr' claims to be 6291456x5 pixels, more than relit reads"),
              std::string::npos)
        << e.what();
  }
  set_int32(2, -3);  // xmax < xmin: a width of -3 - 0 + 1
  io::write_file_atomic(path, bytes);
  try {
    read_image(path);
    FAIL() << "no error for an empty data window";
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find("its data window is -2x5 pixels"), std::string::npos) << e.what();
  }
}

TEST(Image, AtomicWriteKeepsTheOldFileWhenWritingFails) {
  test::TempDir dir("image");
  const std::string path = (dir.path() / "a.exr").string();
  write_image(path, Image(3, 3, 3, 1.5f));
  Image bad(3, 3, 3);
  bad.pixels.resize(2);  // inconsistent: rejected before anything is touched
  EXPECT_THROW(write_image(path, bad), InvalidArgument);
  EXPECT_EQ(read_image(path).pixels, std::vector<float>(27, 1.5f));
  io::write_file_atomic((dir.path() / "t.json").string(), "{}");
  std::ifstream f(dir.path() / "t.json");
  std::string s;
  f >> s;
  EXPECT_EQ(s, "{}");
}

TEST(Progress, TrackerReportsRateEtaAndCancels) {
  std::vector<Progress> seen;
  ProgressTracker t(
      [&](const Progress& p) {
        seen.push_back(p);
        return p.done < 3;
      },
      10, "views");
  t.update(1, "a");
  t.update(2, "b");
  EXPECT_THROW(t.update(3, "c"), Cancelled);
  ASSERT_EQ(seen.size(), 3u);
  EXPECT_EQ(seen[1].done, 2u);
  EXPECT_EQ(seen[1].total, 10u);
  EXPECT_EQ(seen[1].message, "b");
  EXPECT_EQ(seen[1].unit, "views");
  EXPECT_GE(seen[1].rate, 0.0);
  EXPECT_NEAR(seen[1].eta, seen[1].rate > 0 ? 8.0 / seen[1].rate : 0.0, 1e-9);
}

TEST(Image, JoinRgbAlphaIsTheInverseOfSplit) {
  Image rgba(3, 2, 4);
  for (std::size_t k = 0; k < rgba.pixels.size(); ++k) rgba.pixels[k] = 0.1f * float(k);
  const auto [rgb, alpha] = split_rgb_alpha(rgba);
  const Image joined = join_rgb_alpha(rgb, alpha, 3, 2);
  EXPECT_EQ(joined.channels, 4);
  EXPECT_EQ(joined.pixels, rgba.pixels);
  const Image plain = join_rgb_alpha(rgb, {}, 3, 2);
  EXPECT_EQ(plain.channels, 3);
  EXPECT_EQ(plain.pixels, rgb);
  EXPECT_THROW(join_rgb_alpha(rgb, alpha, 2, 3 + 1), InvalidArgument);
  EXPECT_THROW(join_rgb_alpha(rgb, std::vector<float>(5, 0.0f), 3, 2), InvalidArgument);
}

}  // namespace relit
