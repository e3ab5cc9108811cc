// Fuzz target: the image reader (read_image, through OpenImageIO). The input is saved under the extension of
// the format its first bytes announce — PNG, OpenEXR, Radiance HDR, PFM or JPEG, the formats relit reads — and
// .png otherwise; OpenImageIO is told not to try its other readers, whose bugs would not be relit's.
#include <relit/io/image.hpp>

#include "fuzz_common.hpp"

#include <OpenImageIO/imageio.h>

#include <cstring>

namespace {
bool starts_with(const std::uint8_t* data, std::size_t size, const char* magic) {
  const std::size_t n = std::strlen(magic);
  return size >= n && std::memcmp(data, magic, n) == 0;
}

const char* extension_of(const std::uint8_t* data, std::size_t size) {
  if (starts_with(data, size, "\x76\x2f\x31\x01")) return ".exr";
  if (starts_with(data, size, "#?")) return ".hdr";
  if (starts_with(data, size, "Pf") || starts_with(data, size, "PF")) return ".pfm";
  if (starts_with(data, size, "\xff\xd8")) return ".jpg";
  return ".png";
}
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  OIIO::attribute("try_all_readers", 0);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = relit::fuzz::write_input(std::string("image") + extension_of(data, size), data, size);
  return relit::fuzz::expect_only_relit_errors([&] { relit::read_image(path); });
}
