// rays.cl: camera rays in the renderer's ray records (see render.cl), for training batches and for images.
//
// Cameras are pinhole, camera-to-world in OpenGL/Blender axes (the camera looks down -z, +y is up, image rows
// grow downward), 16 floats each: the 3x4 camera-to-world matrix row by row, then fx, fy, cx, cy in pixels.
// Lights, 8 floats per image: position.xyz, 0, RGB intensity [W/sr], 0.
#include "common.clh"

#define RAY_FLOATS 20

inline void write_ray(__global float* ray, __global const float* cam, float px, float py, __global const float* light) {
  const float x = (px - cam[14]) / cam[12];
  const float y = -(py - cam[15]) / cam[13];
  // world direction = R (x, y, -1)
  float3 d = (float3)(fma(cam[0], x, fma(cam[1], y, -cam[2])), fma(cam[4], x, fma(cam[5], y, -cam[6])),
                      fma(cam[8], x, fma(cam[9], y, -cam[10])));
  d = normalize(d);
  ray[0] = cam[3];
  ray[1] = cam[7];
  ray[2] = cam[11];
  ray[3] = 0.0f;
  ray[4] = d.x;
  ray[5] = d.y;
  ray[6] = d.z;
  ray[7] = 0.0f;
  for (int i = 0; i < 8; ++i) ray[8 + i] = light[i];
  ray[16] = ray[17] = ray[18] = ray[19] = 0.0f;  // background: black unless the caller fills it in
}

// A training batch: ray j of iteration `iteration` looks through a pixel centre of an image, both drawn
// uniformly from (seed, iteration, j). Writes the ray and the pixel's RGB target.
__kernel void training_rays(const uint n_rays, const uint seed, const uint iteration, const uint n_images,
                            const uint width, const uint height, __global const float* restrict cameras,
                            __global const float* restrict lights, __global const float* restrict images,
                            __global float* restrict rays, __global float* restrict targets,
                            __global uint* restrict pixel_ids) {
  const uint j = get_global_id(0);
  if (j >= n_rays) return;
  const uint h = relit_hash2(relit_hash2(seed, iteration), j);
  const uint image = h % n_images;
  const uint pixel = relit_hash(h ^ 0x9e3779b9u) % (width * height);
  const uint px = pixel % width, py = pixel / width;
  write_ray(rays + (size_t)j * RAY_FLOATS, cameras + (size_t)image * 16, px + 0.5f, py + 0.5f,
            lights + (size_t)image * 8);
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
  write_ray(rays + (size_t)j * RAY_FLOATS, camera, (pixel % width) + ox, (pixel / width) + oy, light);
}

// n directions uniform on the unit sphere from (seed, iteration, k), as an n x 3 tiled matrix.
__kernel void sphere_directions(const uint n, const uint seed, const uint iteration, __global float* restrict dirs) {
  const uint k = get_global_id(0);
  if (k >= n) return;
  const uint h = relit_hash2(relit_hash2(seed ^ 0x5bd1e995u, iteration), k);
  const float z = 1.0f - 2.0f * relit_uniform(h);
  const float phi = 2.0f * M_PI_F * relit_uniform(relit_hash(h ^ 0x68e31da4u));
  const float r = sqrt(fmax(0.0f, 1.0f - z * z));
  const size_t base = ((size_t)(k / 16) * 3) * 16 + k % 16;
  dirs[base] = r * cos(phi);
  dirs[base + 16] = r * sin(phi);
  dirs[base + 32] = z;
}
