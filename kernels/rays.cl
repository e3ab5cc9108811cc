// rays.cl: camera rays in the renderer's ray records (layout.clh), for training batches and for images.
//
// Cameras are pinhole, camera-to-world in OpenGL/Blender axes (the camera looks down -z, +y is up, image rows
// grow downward), and each image has one point light: the camera and light records of layout.clh.
#include "common.clh"
#include "layout.clh"

inline void write_ray(__global float* ray, __global const float* cam, float px, float py, __global const float* light) {
  __global const float* m = cam + RELIT_CAMERA_TO_WORLD;
  const float x = (px - cam[RELIT_CAMERA_CENTRE]) / cam[RELIT_CAMERA_FOCAL];
  const float y = -(py - cam[RELIT_CAMERA_CENTRE + 1]) / cam[RELIT_CAMERA_FOCAL + 1];
  // world direction = R (x, y, -1)
  float3 d = (float3)(fma(m[0], x, fma(m[1], y, -m[2])), fma(m[4], x, fma(m[5], y, -m[6])),
                      fma(m[8], x, fma(m[9], y, -m[10])));
  d = normalize(d);
  ray_write(ray, (float3)(m[3], m[7], m[11]), d, light);  // background: black unless the caller fills it in
}

// A training batch: ray j of iteration `iteration` looks through a pixel centre of an image, both drawn
// uniformly from (seed, iteration, j). Writes the ray and the pixel's RGB target. Local ray j is ray
// ray_first + ray_stride j of the global batch (a rank's share, relit/parallel.hpp).
__kernel void training_rays(const uint n_rays, const uint seed, const uint iteration, const uint n_images,
                            const uint width, const uint height, __global const float* restrict cameras,
                            __global const float* restrict lights, __global const float* restrict images,
                            __global float* restrict rays, __global float* restrict targets,
                            __global uint* restrict pixel_ids, const uint ray_first, const uint ray_stride) {
  const uint j = get_global_id(0);
  if (j >= n_rays) return;
  const uint h = relit_hash2(relit_hash2(seed, iteration), ray_first + ray_stride * j);
  const uint image = h % n_images;
  const uint pixel = relit_hash(h ^ 0x9e3779b9u) % (width * height);
  const uint px = pixel % width, py = pixel / width;
  write_ray(RAY_RECORD(rays, j), cameras + (size_t)image * RELIT_CAMERA_FLOATS, px + 0.5f, py + 0.5f,
            lights + (size_t)image * RELIT_LIGHT_FLOATS);
  const size_t src = ((size_t)image * width * height + pixel) * 3;
  targets[3 * j] = images[src];
  targets[3 * j + 1] = images[src + 1];
  targets[3 * j + 2] = images[src + 2];
  pixel_ids[j] = image * width * height + pixel;
}

// The rays of pixels [first, first + n_rays) of one image (row-major pixel order), for rendering in tiles.
// Each ray passes through the point (ox, oy) of its pixel (0.5, 0.5: the centre).
__kernel void image_rays(const uint n_rays, const uint first, const uint width, const float ox, const float oy,
                         __global const float* restrict camera, __global const float* restrict light,
                         __global float* restrict rays) {
  const uint j = get_global_id(0);
  if (j >= n_rays) return;
  const uint pixel = first + j;
  write_ray(RAY_RECORD(rays, j), camera, (pixel % width) + ox, (pixel / width) + oy, light);
}

// n directions uniform on the unit sphere from (seed, iteration, k), as an n x 3 tiled matrix.
__kernel void sphere_directions(const uint n, const uint seed, const uint iteration, __global float* restrict dirs) {
  const uint k = get_global_id(0);
  if (k >= n) return;
  const uint h = relit_hash2(relit_hash2(seed ^ 0x5bd1e995u, iteration), k);
  const float z = 1.0f - 2.0f * relit_uniform(h);
  const float phi = 2.0f * M_PI_F * relit_uniform(relit_hash(h ^ 0x68e31da4u));
  const float r = sqrt(fmax(0.0f, 1.0f - z * z));
  TILED(dirs, 3, k, 0) = r * cos(phi);
  TILED(dirs, 3, k, 1) = r * sin(phi);
  TILED(dirs, 3, k, 2) = z;
}
