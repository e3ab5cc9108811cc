// Camera rays: directions against a double-precision pinhole model, training batches that look up the right
// pixels, cover every image, and are reproducible.
#include "test_support.hpp"

#include <relit/render/rays.hpp>
#include <relit/render/volume_renderer.hpp>

#include <Eigen/Geometry>

#include <cmath>

#include <cmath>
#include <set>

namespace relit {

using render::kRayFloats;

namespace {
// A camera at `eye` looking at the origin with +z up.
Camera camera_at(const Eigen::Vector3d& eye, float fov, int w, int h) {
  return Camera::look_at({float(eye.x()), float(eye.y()), float(eye.z())}, {0, 0, 0}, {0, 0, 1}, fov, w, h);
}

// An independent pinhole model: direction through pixel position (px, py).
Eigen::Vector3d reference_dir(const Camera& c, double px, double py) {
  const double f = 0.5 * c.width / std::tan(0.5 * c.camera_angle_x);
  const Eigen::Vector3d local((px - 0.5 * c.width) / f, -(py - 0.5 * c.height) / f, -1);
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) R(r, k) = c.transform[r][k];
  return (R * local).normalized();
}
}  // namespace

TEST(Rays, ImageRaysMatchThePinholeModel) {
  const Device d = test::test_device();
  const std::uint32_t w = 33, h = 21;
  const Camera cam = camera_at({3, -2, 1.5}, 0.7f, w, h);
  const PointLight light{{1, 2, 3}, {100, 200, 300}};
  Buffer<float> rays(d, w * h * kRayFloats);
  render::image_rays(d, cam, light, 0, w * h, rays);
  const auto r = rays.read();
  for (std::uint32_t p = 0; p < w * h; ++p) {
    const Eigen::Vector3d ref = reference_dir(cam, p % w + 0.5, p / w + 0.5);
    const auto host = cam.direction(p % w + 0.5, p / w + 0.5);  // the scene's own camera model agrees
    for (int k = 0; k < 3; ++k) {
      ASSERT_NEAR(r[p * kRayFloats + render::kRayDirection + k], ref[k], 1e-6) << "pixel " << p;
      ASSERT_NEAR(host[k], ref[k], 1e-6) << "pixel " << p;
    }
    ASSERT_EQ(r[p * kRayFloats + render::kRayOrigin], 3.0f);
    ASSERT_EQ(r[p * kRayFloats + render::kRayLightIntensity], 100.0f);
    ASSERT_EQ(r[p * kRayFloats + render::kRayLightPosition + 2], 3.0f);
  }
  // The centre pixel (odd size) looks straight at the target; the left edge is fov/2 away from it.
  const std::uint32_t centre = (h / 2) * w + w / 2;
  const Eigen::Vector3d to_target = -Eigen::Vector3d(3, -2, 1.5).normalized();
  Eigen::Vector3d dc(r[centre * kRayFloats + render::kRayDirection], r[centre * kRayFloats + render::kRayDirection + 1],
                     r[centre * kRayFloats + render::kRayDirection + 2]);
  EXPECT_NEAR(dc.dot(to_target), 1.0, 1e-6);
  const double edge = std::atan((0.5 * w - 0.5) / cam.focal());
  const std::uint32_t left = (h / 2) * w;
  Eigen::Vector3d dl(r[left * kRayFloats + render::kRayDirection], r[left * kRayFloats + render::kRayDirection + 1],
                     r[left * kRayFloats + render::kRayDirection + 2]);
  EXPECT_NEAR(std::acos(dl.dot(to_target)), edge, 1e-5);
}

TEST(Rays, ImageRaysPassThroughTheGivenPointOfEachPixel) {
  const Device d = test::test_device();
  const std::uint32_t w = 7, h = 5;
  const Camera cam = camera_at({-2, 3, 1}, 0.9f, w, h);
  const PointLight light{{1, 2, 3}, {100, 200, 300}};
  Buffer<float> rays(d, w * h * kRayFloats);
  for (const std::array<float, 2> off : {std::array<float, 2>{0.25f, 0.75f}, std::array<float, 2>{0.0f, 1.0f}}) {
    render::image_rays(d, cam, light, 0, w * h, rays, off);
    const auto r = rays.read();
    for (std::uint32_t p = 0; p < w * h; ++p) {
      const Eigen::Vector3d ref = reference_dir(cam, p % w + off[0], p / w + off[1]);
      for (int k = 0; k < 3; ++k)
        ASSERT_NEAR(r[p * kRayFloats + render::kRayDirection + k], ref[k], 1e-6) << "pixel " << p;
    }
  }
  EXPECT_THROW(render::image_rays(d, cam, light, 0, w * h, rays, {0.5f, 1.5f}), InvalidArgument);
  EXPECT_THROW(render::image_rays(d, cam, light, 0, w * h, rays, {std::nanf(""), 0.5f}), InvalidArgument);
}

TEST(Rays, SamplesPerPixelFormAGridOfCellCentres) {
  EXPECT_EQ(render::pixel_sample_offset(1, 0), (std::array<float, 2>{0.5f, 0.5f}));
  const std::array<std::array<float, 2>, 4> four{{{0.25f, 0.25f}, {0.75f, 0.25f}, {0.25f, 0.75f}, {0.75f, 0.75f}}};
  for (std::uint32_t s = 0; s < 4; ++s) EXPECT_EQ(render::pixel_sample_offset(4, s), four[s]) << "sample " << s;
  EXPECT_FLOAT_EQ(render::pixel_sample_offset(9, 5)[0], 2.5f / 3.0f);
  EXPECT_FLOAT_EQ(render::pixel_sample_offset(9, 5)[1], 1.5f / 3.0f);
  for (std::uint32_t bad : {0u, 2u, 3u, 8u}) EXPECT_THROW(render::pixel_sample_offset(bad, 0), InvalidArgument) << bad;
  EXPECT_THROW(render::pixel_sample_offset(4, 4), InvalidArgument);
}

TEST(Rays, TrainingBatchesLookUpTheirPixelsCoverAllImagesAndAreReproducible) {
  const Device d = test::test_device();
  const std::uint32_t w = 8, h = 6, n_images = 5, n_rays = 2000;
  std::vector<Camera> cams;
  std::vector<PointLight> lights;
  std::vector<float> images;
  for (std::uint32_t i = 0; i < n_images; ++i) {
    cams.push_back(camera_at({4.0 * std::cos(i), 4.0 * std::sin(i), 1}, 0.6f, w, h));
    lights.push_back({{float(i), 0, 5}, {float(10 * i), 1, 2}});
    for (std::uint32_t p = 0; p < w * h * 3; ++p) images.push_back(float(i * 1000 + p));
  }
  const render::RaySource source(d, cams, lights, images);
  Buffer<float> rays(d, n_rays * kRayFloats), targets(d, 3 * n_rays), rays2(d, n_rays * kRayFloats), t2(d, 3 * n_rays);
  Buffer<std::uint32_t> ids(d, n_rays), ids2(d, n_rays);
  source.training_batch(n_rays, 7, 3, rays, targets, ids);
  const auto r = rays.read(), t = targets.read();
  const auto id = ids.read();
  std::set<std::uint32_t> seen_images;
  for (std::uint32_t j = 0; j < n_rays; ++j) {
    const std::uint32_t image = id[j] / (w * h), pixel = id[j] % (w * h);
    seen_images.insert(image);
    for (int c = 0; c < 3; ++c) ASSERT_EQ(t[3 * j + c], float(image * 1000 + pixel * 3 + c));
    const Eigen::Vector3d ref = reference_dir(cams[image], pixel % w + 0.5, pixel / w + 0.5);
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(r[j * kRayFloats + render::kRayDirection + k], ref[k], 1e-6);
    ASSERT_EQ(r[j * kRayFloats + render::kRayLightIntensity], float(10 * image));
  }
  EXPECT_EQ(seen_images.size(), n_images);
  source.training_batch(n_rays, 7, 3, rays2, t2, ids2);
  EXPECT_EQ(ids2.read(), id);
  source.training_batch(n_rays, 7, 4, rays2, t2, ids2);
  EXPECT_NE(ids2.read(), id);
}

TEST(Rays, BadInputsAreErrors) {
  const Device d = test::test_device();
  const Camera cam = camera_at({0, 4, 0}, 0.5f, 4, 4);
  EXPECT_THROW(render::RaySource(d, {cam}, {}, std::vector<float>(48)), InvalidArgument);
  EXPECT_THROW(render::RaySource(d, {cam}, {PointLight{}}, std::vector<float>(47)), InvalidArgument);
  EXPECT_THROW(render::RaySource(d, {cam, camera_at({0, 4, 0}, 0.5f, 5, 4)}, {PointLight{}, PointLight{}},
                                 std::vector<float>(96)),
               InvalidArgument);
  PointLight negative;
  negative.intensity = {-1, 0, 0};
  EXPECT_THROW(render::RaySource(d, {cam}, {negative}, std::vector<float>(48)), Error);
}

}  // namespace relit
