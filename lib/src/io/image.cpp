// Image I/O through OpenImageIO, with atomic writes (temporary file in the target folder + rename).
#include <relit/error.hpp>
#include <relit/io/file.hpp>
#include <relit/io/image.hpp>

#if RELIT_WITH_OPENIMAGEIO
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#endif

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <unistd.h>

namespace fs = std::filesystem;

namespace relit {

namespace {

// A corrupt or forged header must not make relit allocate what no image of its needs. OpenImageIO reads in
// chunks of up to 256 rows whatever the height, so the row length is bounded too.
constexpr std::uint64_t kMaxValues = std::uint64_t(1) << 28;     // 1 GiB of floats: 16384 x 16384 x 1, 8192^2 x 4
constexpr std::uint64_t kMaxRowValues = std::uint64_t(1) << 18;  // 65536 x 4, 16384 x 16

[[noreturn]] void fail_too_large(const std::string& path, std::int64_t width, std::int64_t height,
                                 const std::string& channels) {
  throw IOError("image '" + path + "' claims to be " + std::to_string(width) + "x" + std::to_string(height) + channels +
                ", more than relit reads (" + std::to_string(kMaxRowValues) + " values a row, " +
                std::to_string(kMaxValues) + " in all): a corrupt header?");
}

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// OpenEXR 3.1 allocates some header attributes (strings, vectors, previews, unknown types), and libpng (as
// OpenImageIO sets it up) each chunk, at the size the file claims before reading it: a corrupt file of a few
// hundred bytes can claim gigabytes. So these must lie inside the file. The EXR headers are walked as OpenEXR
// 3.1 reads them (Header::readFrom): attributes of fixed-size types (box2i, v2f, compression, ...) and channel
// lists are read at their own length whatever size the file claims, so the walk must skip them the same way or it
// falls out of step with OpenEXR. Headers are small: the first MiB is checked, what lies beyond is left to the
// format's reader. The data window and the tile size are checked against relit's size limits here too: OpenEXR
// allocates its line and tile buffers when it opens a file (a 212-byte file claiming one row of 6.3 million
// pixels made it allocate and clear 150 MB).
void check_exr_header(const std::string& path, const std::string& head, std::uint64_t file_size) {
  const auto uint32_at = [&](std::size_t at) {
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= std::uint32_t(static_cast<unsigned char>(head[at + i])) << (8 * i);
    return v;
  };
  const auto corrupt = [&](const std::string& what) {
    throw IOError("image '" + path + "' is a corrupt OpenEXR file: " + what + " (truncated or corrupt)");
  };
  const auto claims = [&](const std::string& what, std::uint64_t size, std::size_t at) {
    if (size > file_size - std::min<std::uint64_t>(file_size, at))
      corrupt(what + " claims " + std::to_string(size) + " bytes at offset " + std::to_string(at) + " of a " +
              std::to_string(file_size) + "-byte file");
  };
  // The bytes OpenEXR 3.1 reads for a value of each fixed-size type.
  static const std::map<std::string, std::size_t> fixed = {{"box2i", 16},    {"box2f", 16},
                                                           {"int", 4},       {"float", 4},
                                                           {"double", 8},    {"v2i", 8},
                                                           {"v2f", 8},       {"v2d", 16},
                                                           {"v3i", 12},      {"v3f", 12},
                                                           {"v3d", 24},      {"m33f", 36},
                                                           {"m33d", 72},     {"m44f", 64},
                                                           {"m44d", 128},    {"compression", 1},
                                                           {"lineOrder", 1}, {"envmap", 1},
                                                           {"rational", 8},  {"timecode", 8},
                                                           {"keycode", 28},  {"chromaticities", 32},
                                                           {"tiledesc", 9},  {"deepImageState", 1}};
  const bool multipart = (uint32_at(4) & 0x1000u) != 0;
  std::size_t at = 8;
  // A NUL-terminated string at `at`; false when the terminator lies beyond what was read.
  const auto text = [&](std::string& out) {
    const std::size_t end = head.find('\0', at);
    if (end == std::string::npos) return false;
    out = head.substr(at, end - at);
    at = end + 1;
    return true;
  };
  std::string name, type;
  for (;;) {                    // headers (several in a multi-part file, ended by an empty one)
    for (;;) {                  // attributes: name\0 type\0 size value; an empty name ends the header
      if (!text(name)) return;  // beyond what was read
      if (name.empty()) break;
      if (!text(type) || at + 4 > head.size()) return;
      const std::uint32_t size = uint32_at(at);
      at += 4;
      const std::string what = "header attribute '" + name + "'";
      if (const auto f = fixed.find(type); f != fixed.end()) {
        if (at + f->second > head.size()) return;
        if (type == "box2i" && name == "dataWindow") {
          const auto int32_at = [&](std::size_t i) { return std::int64_t(std::int32_t(uint32_at(at + 4 * i))); };
          const std::int64_t width = int32_at(2) - int32_at(0) + 1, height = int32_at(3) - int32_at(1) + 1;
          if (width <= 0 || height <= 0)
            throw IOError("image '" + path + "' is a corrupt OpenEXR file: its data window is " +
                          std::to_string(width) + "x" + std::to_string(height) + " pixels");
          if (std::uint64_t(width) > kMaxRowValues || std::uint64_t(width) * std::uint64_t(height) > kMaxValues)
            fail_too_large(path, width, height, " pixels");
        }
        if (type == "tiledesc") {
          const std::uint64_t tx = uint32_at(at), ty = uint32_at(at + 4);
          if (tx > kMaxRowValues || tx * ty > kMaxValues)
            throw IOError("image '" + path + "' claims tiles of " + std::to_string(tx) + "x" + std::to_string(ty) +
                          " pixels, more than relit reads: a corrupt header?");
        }
        at += f->second;
      } else if (type == "chlist") {  // name\0 + 16 bytes per channel, up to an empty name
        std::string channel;
        for (;;) {
          if (!text(channel)) return;
          if (channel.empty()) break;
          at += 16;
          if (at > head.size()) return;
        }
      } else if (type == "preview") {  // width, height, then width x height RGBA bytes
        if (at + 8 > head.size()) return;
        claims(what + " (a " + std::to_string(uint32_at(at)) + "x" + std::to_string(uint32_at(at + 4)) + " preview)",
               std::uint64_t(uint32_at(at)) * uint32_at(at + 4) * 4, at + 8);
        at += 8 + std::size_t(std::uint64_t(uint32_at(at)) * uint32_at(at + 4) * 4);
      } else {  // string, stringvector, floatvector and unknown (opaque) types: read at the claimed size
        claims(what, size, at);
        if (type == "stringvector")
          for (std::size_t p = at; p + 4 <= at + size && p + 4 <= head.size();) {
            const std::uint32_t n = uint32_at(p);
            claims(what + ": a string of it", n, p + 4);
            p += 4 + std::size_t(n);
          }
        at += size;
      }
      if (at >= head.size()) return;
    }
    if (!multipart || at >= head.size() || head[at] == '\0') return;
  }
}

void check_claimed_sizes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  const std::uint64_t file_size = fs::file_size(path);
  std::string head(std::size_t(std::min<std::uint64_t>(file_size, std::uint64_t(1) << 20)), '\0');
  f.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(f.gcount()));
  const auto uint32_at = [&](std::size_t at, bool big_endian) {
    std::uint32_t v = 0;
    for (int i = 0; i < 4; ++i)
      v |= std::uint32_t(static_cast<unsigned char>(head[at + i])) << (8 * (big_endian ? 3 - i : i));
    return v;
  };
  const auto fail = [&](const std::string& format, const std::string& what, std::uint32_t size, std::size_t at) {
    throw IOError("image '" + path + "' is a corrupt " + format + " file: " + what + " claims " + std::to_string(size) +
                  " bytes at offset " + std::to_string(at) + " of a " + std::to_string(file_size) +
                  "-byte file (truncated or corrupt)");
  };
  if (head.size() >= 8 && head.compare(0, 4, "\x76\x2f\x31\x01") == 0) {
    check_exr_header(path, head, file_size);
  } else if (head.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0) {  // PNG: signature, then length type data crc
    for (std::size_t at = 8; at + 8 <= head.size();) {
      const std::uint32_t size = uint32_at(at, true);
      const std::string type = head.substr(at + 4, 4);
      at += 8;
      if (size > file_size - at) fail("PNG", "chunk '" + type + "'", size, at);
      if (type == "IEND") return;
      at += std::size_t(size) + 4;
    }
  }
}

bool is_float_format(const std::string& ext) { return ext == ".exr" || ext == ".hdr" || ext == ".pfm"; }
bool is_8bit_format(const std::string& ext) { return ext == ".png" || ext == ".jpg" || ext == ".jpeg"; }

#if !RELIT_WITH_OPENIMAGEIO
[[noreturn]] void fail_without_image_io(const std::string& what, const std::string& path) {
  throw IOError("cannot " + what + " '" + path +
                "': this relit was built without OpenImageIO (RELIT_WITH_OPENIMAGEIO=OFF), so it reads and writes no "
                "image files");
}
#endif

}  // namespace

float linear_to_srgb(float x) {
  x = std::clamp(std::isfinite(x) ? x : 0.0f, 0.0f, 1.0f);
  return x <= 0.0031308f ? 12.92f * x : 1.055f * std::pow(x, 1.0f / 2.4f) - 0.055f;
}

float srgb_to_linear(float x) { return x <= 0.04045f ? x / 12.92f : std::pow((x + 0.055f) / 1.055f, 2.4f); }

Image read_image(const std::string& path) {
  if (!fs::exists(path)) throw IOError("image file '" + path + "' does not exist");
  // A folder, a FIFO or a device (/dev/stdin would block) is no image.
  if (!fs::is_regular_file(path)) throw IOError("image file '" + path + "' is not a regular file");
  check_claimed_sizes(path);
#if !RELIT_WITH_OPENIMAGEIO
  fail_without_image_io("read image", path);
#else
  auto in = OIIO::ImageInput::open(path);
  if (!in)
    throw IOError("cannot read image '" + path + "': " + OIIO::geterror() + " (is it a valid EXR/HDR/PNG file?)");
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.depth > 1)
    throw IOError("image '" + path + "' has an unsupported shape " + std::to_string(spec.width) + "x" +
                  std::to_string(spec.height) + "x" + std::to_string(spec.nchannels));
  const std::uint64_t row = std::uint64_t(spec.width) * std::uint64_t(spec.nchannels);
  const std::uint64_t values = row * std::uint64_t(spec.height);
  if (values > kMaxValues || row > kMaxRowValues)
    fail_too_large(path, spec.width, spec.height, "x" + std::to_string(spec.nchannels));
  // Netpbm files (PFM, PPM, PGM, PBM) are not compressed: the pixels the header claims must be in the file (a PBM
  // packs 8 to a byte). OpenImageIO would otherwise allocate the claimed size first (2.4 GB for 20 bytes).
  if (std::string(in->format_name()) == "pnm" && values * spec.format.size() / 8 > fs::file_size(path))
    throw IOError("image '" + path + "' is a truncated or corrupt " + in->format_name() + " file: its header claims " +
                  std::to_string(spec.width) + "x" + std::to_string(spec.height) + "x" +
                  std::to_string(spec.nchannels) + " pixels, the file has " + std::to_string(fs::file_size(path)) +
                  " bytes");
  Image image(spec.width, spec.height, spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.pixels.data()))
    throw IOError("cannot read the pixels of image '" + path + "': " + in->geterror() +
                  " (truncated or corrupt file?)");
  in->close();
  // Integer formats hold sRGB-encoded colour (PNG, JPEG); relit works in linear radiance.
  const bool encoded = spec.format.basetype != OIIO::TypeDesc::FLOAT && spec.format.basetype != OIIO::TypeDesc::HALF &&
                       spec.format.basetype != OIIO::TypeDesc::DOUBLE;
  if (encoded) {
    const int colour = std::min(spec.nchannels, spec.alpha_channel >= 0 ? spec.alpha_channel : 3);
    for (std::size_t p = 0; p < image.pixels.size(); p += spec.nchannels)
      for (int c = 0; c < colour; ++c) image.pixels[p + c] = srgb_to_linear(image.pixels[p + c]);
  }
  for (float v : image.pixels)
    if (!std::isfinite(v)) throw IOError("image '" + path + "' contains NaN or infinite values");
  return image;
#endif
}

void write_image(const std::string& path, const Image& image) {
  if (image.empty() || image.width <= 0 || image.height <= 0 || image.channels <= 0 ||
      image.pixels.size() != std::size_t(image.width) * image.height * image.channels)
    throw InvalidArgument("cannot write '" + path + "': the image is empty or its size does not match its pixels");
  const std::string ext = lower_extension(path);
  if (!is_float_format(ext) && !is_8bit_format(ext))
    throw InvalidArgument("cannot write '" + path + "': unsupported extension '" + ext +
                          "' (use .exr for linear float or .png for 8-bit sRGB)");
  const fs::path target(path);
  if (target.has_parent_path() && !fs::is_directory(target.parent_path()))
    throw IOError("cannot write '" + path + "': folder '" + target.parent_path().string() + "' does not exist");

#if !RELIT_WITH_OPENIMAGEIO
  fail_without_image_io("write", path);
#else
  const fs::path tmp = io::temporary_sibling(target.string());
  auto out = OIIO::ImageOutput::create(tmp.string());
  if (!out) throw IOError("cannot write '" + path + "': " + OIIO::geterror());
  const bool eight_bit = is_8bit_format(ext);
  OIIO::ImageSpec spec(image.width, image.height, image.channels,
                       eight_bit ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::FLOAT);
  if (image.channels == 4) spec.alpha_channel = 3;
  if (eight_bit)
    spec.attribute("oiio:ColorSpace", "sRGB");
  else
    spec.attribute("compression", "zip");
  // OpenImageIO stamps EXR files with the time of writing (capDate) unless told a DateTime: an empty one keeps
  // the bytes a function of the pixels alone, so a dataset generated twice, or by several MPI ranks, is identical.
  spec.attribute("DateTime", "");

  std::vector<float> data = image.pixels;
  if (eight_bit) {
    const int colour = std::min(image.channels, 3);
    for (std::size_t p = 0; p < data.size(); p += image.channels) {
      for (int c = 0; c < colour; ++c) data[p + c] = linear_to_srgb(data[p + c]);
      for (int c = colour; c < image.channels; ++c) data[p + c] = std::clamp(data[p + c], 0.0f, 1.0f);
    }
  }
  const bool ok = out->open(tmp.string(), spec) && out->write_image(OIIO::TypeDesc::FLOAT, data.data()) && out->close();
  if (!ok) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw IOError("cannot write '" + path + "': " + out->geterror());
  }
  io::replace_file(tmp.string(), target.string());
#endif
}

std::pair<std::vector<float>, std::vector<float>> split_rgb_alpha(const Image& img) {
  if (img.channels < 3)
    throw InvalidArgument("split_rgb_alpha: an image of " + std::to_string(img.channels) + " channels has no RGB");
  const std::size_t pixels = std::size_t(img.width) * img.height;
  std::vector<float> rgb(pixels * 3), alpha(img.channels >= 4 ? pixels : 0);
  for (std::size_t p = 0; p < pixels; ++p) {
    for (int c = 0; c < 3; ++c) rgb[p * 3 + c] = img.pixels[p * img.channels + c];
    if (!alpha.empty()) alpha[p] = img.pixels[p * img.channels + 3];
  }
  return {std::move(rgb), std::move(alpha)};
}

Image join_rgb_alpha(const std::vector<float>& rgb, const std::vector<float>& alpha, int width, int height) {
  const std::size_t pixels = std::size_t(width) * height;
  if (width <= 0 || height <= 0 || rgb.size() != pixels * 3 || (!alpha.empty() && alpha.size() != pixels))
    throw InvalidArgument("join_rgb_alpha: " + std::to_string(rgb.size()) + " RGB and " + std::to_string(alpha.size()) +
                          " alpha values for a " + std::to_string(width) + " x " + std::to_string(height) + " image");
  Image img(width, height, alpha.empty() ? 3 : 4);
  for (std::size_t p = 0; p < pixels; ++p) {
    for (int c = 0; c < 3; ++c) img.pixels[p * img.channels + c] = rgb[p * 3 + c];
    if (!alpha.empty()) img.pixels[p * 4 + 3] = alpha[p];
  }
  return img;
}

bool draw_text(Image& image, int x, int y, const std::string& text, int size, float value, TextAlign align) {
  if (image.empty() || text.empty() || size <= 0) return true;
#if !RELIT_WITH_OPENIMAGEIO
  (void)x, (void)y, (void)value, (void)align;
  return false;  // no font renderer: the contact sheets go without their titles
#else
  OIIO::ImageBuf buf(OIIO::ImageSpec(image.width, image.height, image.channels, OIIO::TypeDesc::FLOAT),
                     image.pixels.data());
  const std::vector<float> colour(std::size_t(image.channels), value);
  const auto alignx = align == TextAlign::Left     ? OIIO::ImageBufAlgo::TextAlignX::Left
                      : align == TextAlign::Center ? OIIO::ImageBufAlgo::TextAlignX::Center
                                                   : OIIO::ImageBufAlgo::TextAlignX::Right;
  // One thread: the glyphs are few, and the result must not depend on the machine.
  return OIIO::ImageBufAlgo::render_text(buf, x, y, text, size, "DejaVuSans", colour, alignx,
                                         OIIO::ImageBufAlgo::TextAlignY::Top, 0, {}, 1);
#endif
}

}  // namespace relit
