// mlp_peers.cl: the element-wise kernels of the unfused MLP peers (a GEMM chain through CLBlast) in the
// benchmarks: bias + activation after each GEMM, and the ReLU mask of the backward pass. Row-major
// [batch][cols] matrices, as the GEMMs produce them.

// z[s][j] = act(z[s][j] + b[j * b_stride]); act: 0 None, 1 ReLU. (The bias is the last column of relit's
// [n_out][n_in + 1] layer matrices, hence the stride.)
__kernel void bias_act(const uint n, const uint cols, __global float* restrict z, __global const float* restrict b,
                       const uint b_offset, const uint b_stride, const uint relu) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  const float v = z[i] + b[b_offset + (i % cols) * b_stride];
  z[i] = relu ? fmax(v, 0.0f) : v;
}

// g[i] = h[i] > 0 ? g[i] : 0 (the ReLU derivative from the layer's output h).
__kernel void relu_mask(const uint n, __global float* restrict g, __global const float* restrict h) {
  const size_t i = get_global_id(0);
  if (i >= n) return;
  g[i] = h[i] > 0.0f ? g[i] : 0.0f;
}

// db[j * db_stride] = sum_s g[s][j], one work-item per column, rows in order.
__kernel void column_sums(const uint rows, const uint cols, __global const float* restrict g,
                          __global float* restrict db, const uint db_offset, const uint db_stride) {
  const size_t j = get_global_id(0);
  if (j >= cols) return;
  float s = 0.0f;
  for (uint r = 0; r < rows; ++r) s += g[(size_t)r * cols + j];
  db[db_offset + j * db_stride] = s;
}
