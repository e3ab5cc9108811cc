// random_access.cl: the device's rate of independent random 8-byte accesses, the memory roofline of the
// hash-grid encoding (whose every table entry is 8 bytes: 2 float features).
//
// Each work-item makes `iters` rounds of 16 accesses to pseudo-random entries of a table of `mask + 1`
// float2 entries (a power of two). The entry indices come from a hash of a counter, never from loaded data,
// so the accesses are independent and the out-of-order core overlaps as many misses as it can: this is the
// best case for random accesses, the rate a kernel whose loads all miss cannot beat.
//   random_read:  sums the entries it reads; all work-items read the same table(s).
//   random_rmw:   adds to the entries (entry += 1), load + store: the parameter-gradient scatter. Each work-item
//                 owns its tables, as a level is owned in the hash-grid backward, so there are no races and
//                 the result is exact: every entry ends at its count of visits.
// Every lane of every round has its own counter: lane l of round r of item g hashes (g * iters + r) * 16 + l.
//
// Tables in turn, the hash grid's level-major order, where each level's table is used for a while and then
// left (so that each pass over the levels brings every table back from memory when together they do not fit
// in the cache): random_read walks `n_tables` consecutive tables of `mask + 1` entries, round r in table
// r * n_tables / iters; work-item g of random_rmw walks its own `n_tables` tables, from table g * n_tables.

inline uint16 ra_index(uint gid, uint iters, uint r, uint mask) {
  const uint16 lane = (uint16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  uint16 h = ((uint16)((gid * iters + r) * 16u) + lane) * 0x9E3779B1u;
  h ^= h >> 15;
  h *= 0x85EBCA77u;
  h ^= h >> 13;
  return h & (uint16)mask;
}

// prefetch != 0: while in a table, also prefetch the next table, a slice per round, sequentially (as the
// hash-grid kernels do on CPUs), so that its random accesses find it in the cache.
inline void ra_prefetch(__global const float2* next, uint mask, uint rounds_per_table, uint round_in_table) {
#if defined(__clang__)
  const uint lines = (mask + 1u) / 8u;  // 8 entries of 8 bytes per 64-byte line
  const uint a = (uint)((ulong)lines * round_in_table / rounds_per_table);
  const uint b = (uint)((ulong)lines * (round_in_table + 1u) / rounds_per_table);
  for (uint i = a; i < b; ++i) __builtin_prefetch(next + (size_t)i * 8u, 0, 3);
#endif
}

__kernel void random_read(const uint iters, const uint mask, const uint n_tables, const uint prefetch,
                          __global const float2* restrict base, __global float* restrict out) {
  const uint gid = (uint)get_global_id(0);
  const uint per_table = iters / n_tables;
  float2 acc[4] = {(float2)0.0f, (float2)0.0f, (float2)0.0f, (float2)0.0f};
  for (uint r = 0; r < iters; ++r) {
    const uint k = (uint)((ulong)r * n_tables / iters);
    __global const float2* table = base + (size_t)k * (mask + 1u);
    if (prefetch && k + 1u < n_tables) ra_prefetch(table + mask + 1u, mask, per_table, r - k * per_table);
    const uint16 i = ra_index(gid, iters, r, mask);
    acc[0] += table[i.s0] + table[i.s4] + table[i.s8] + table[i.sc];
    acc[1] += table[i.s1] + table[i.s5] + table[i.s9] + table[i.sd];
    acc[2] += table[i.s2] + table[i.s6] + table[i.sa] + table[i.se];
    acc[3] += table[i.s3] + table[i.s7] + table[i.sb] + table[i.sf];
  }
  const float2 s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
  out[gid] = s.x + s.y;
}

__kernel void random_rmw(const uint iters, const uint mask, const uint n_tables, const uint prefetch,
                         __global float2* restrict table) {
  const uint gid = (uint)get_global_id(0);
  const uint per_table = iters / n_tables;
  for (uint r = 0; r < iters; ++r) {
    const uint k = (uint)((ulong)r * n_tables / iters);
    __global float2* t = table + ((size_t)gid * n_tables + k) * (mask + 1u);
    if (prefetch && k + 1u < n_tables) ra_prefetch(t + mask + 1u, mask, per_table, r - k * per_table);
    uint idx[16];
    vstore16(ra_index(gid, iters, r, mask), 0, idx);
#pragma unroll
    for (int l = 0; l < 16; ++l) t[idx[l]] += (float2)1.0f;
  }
}
