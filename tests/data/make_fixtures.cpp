// Writes the small test fixtures of this folder (run once; the outputs are committed):
//   sphere_fog.vdb  an OpenVDB fog volume: a sphere of radius 10 voxels, density falling off smoothly
//   env_small.exr   a 32x16 lat-long environment map: a sky gradient with a bright spot at +x, 30 degrees up
// Build: g++ -std=c++17 -O1 make_fixtures.cpp -lopenvdb -ltbb -lOpenImageIO -lOpenImageIO_Util -o make_fixtures
#include <OpenImageIO/imageio.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>
#include <openvdb/tools/LevelSetUtil.h>

#include <cmath>
#include <vector>

int main() {
  openvdb::initialize();
  auto sdf = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(10.0f, openvdb::Vec3f(3, -2, 5), 1.0f, 4.0f);
  openvdb::tools::sdfToFogVolume(*sdf);
  sdf->setName("density");
  openvdb::io::File("sphere_fog.vdb").write({sdf});

  const int w = 32, h = 16;
  std::vector<float> px(w * h * 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float up = std::cos((y + 0.5f) / h * 3.14159265f);
      float* p = &px[(y * w + x) * 3];
      p[0] = 0.3f + 0.2f * up, p[1] = 0.4f + 0.2f * up, p[2] = 0.6f + 0.3f * up;
      if (x == 0 && y == 5) p[0] = p[1] = p[2] = 50.0f;
    }
  auto out = OIIO::ImageOutput::create("env_small.exr");
  out->open("env_small.exr", OIIO::ImageSpec(w, h, 3, OIIO::TypeDesc::FLOAT));
  out->write_image(OIIO::TypeDesc::FLOAT, px.data());
  out->close();
  return 0;
}
