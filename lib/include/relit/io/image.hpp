// Images on the host and on disk, through OpenImageIO. The file extension chooses the format:
//   .exr (and .hdr, .pfm)  linear float, written as 32-bit float EXR channels R, G, B[, A]
//   .png (and .jpg)        8-bit, sRGB-encoded from linear values clamped to [0, 1]; alpha stays linear
// Writes are atomic: the image goes to a temporary file in the same folder which is then renamed, so a
// reader never sees half a file and an interrupted write leaves the old file intact.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace relit {

/// A linear float image, row-major from the top row, channels interleaved.
struct Image {
  int width = 0, height = 0, channels = 0;
  std::vector<float> pixels;  ///< width * height * channels values

  Image() = default;
  Image(int w, int h, int c, float value = 0.0f)
      : width(w), height(h), channels(c), pixels(std::size_t(w) * h * c, value) {}
  float& at(int x, int y, int c) { return pixels[(std::size_t(y) * width + x) * channels + c]; }
  float at(int x, int y, int c) const { return pixels[(std::size_t(y) * width + x) * channels + c]; }
  bool empty() const { return pixels.empty(); }
};

/// Reads any image OpenImageIO can read as linear float (8-bit sRGB formats are decoded to linear).
/// Throws IOError naming the file when it is missing, unreadable or corrupt.
Image read_image(const std::string& path);

/// Writes `image` to `path` (format by extension, see above) atomically. Throws IOError on failure and
/// InvalidArgument for an empty image or an unsupported extension.
void write_image(const std::string& path, const Image& image);

/// The first three channels of an image with three or more (RGB, h x w x 3) and its fourth (alpha, h x w; empty
/// with three channels). Throws InvalidArgument for fewer than three.
std::pair<std::vector<float>, std::vector<float>> split_rgb_alpha(const Image& image);

/// The inverse: a width x height image of `rgb` (h x w x 3) with `alpha` (h x w) as its fourth channel, or RGB
/// when `alpha` is empty. Throws InvalidArgument when a size does not match.
Image join_rgb_alpha(const std::vector<float>& rgb, const std::vector<float>& alpha, int width, int height);

enum class TextAlign { Left, Center, Right };

/// Draws one line of `text` into `image` (any channel count, linear values) with its top at `y` and its left
/// edge, centre or right edge at `x`, `size` pixels high, every channel set to `value` under the glyphs (an
/// "over" with the glyphs' coverage), clipped to the image. The font is DejaVu Sans (Debian's
/// fonts-dejavu-core), found by OpenImageIO. Returns false, drawing nothing, when the font cannot be found.
bool draw_text(Image& image, int x, int y, const std::string& text, int size, float value,
               TextAlign align = TextAlign::Left);

/// sRGB transfer function of a linear value clamped to [0, 1].
float linear_to_srgb(float linear);
float srgb_to_linear(float encoded);

}  // namespace relit
