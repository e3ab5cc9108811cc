// Buffer<T>: round trips, fills, copies, and bounds checks that name the offending range.
#include "test_support.hpp"

#include <numeric>

namespace relit {

TEST(Buffer, WriteReadRoundTrip) {
  const Device d = test::test_device();
  std::vector<float> host(1000);
  std::iota(host.begin(), host.end(), -3.5f);
  Buffer<float> b(d, host);
  EXPECT_EQ(b.size(), host.size());
  EXPECT_EQ(b.bytes(), host.size() * sizeof(float));
  EXPECT_EQ(b.read(), host);
  // Partial write and read at an offset.
  const std::vector<float> patch = {1.f, 2.f, 3.f};
  b.write(patch, 997);
  std::vector<float> tail(3);
  b.read(tail.data(), 3, 997);
  EXPECT_EQ(tail, patch);
}

TEST(Buffer, FillAndCopy) {
  const Device d = test::test_device();
  Buffer<int> a(d, 64), c(d, 64);
  a.fill(7);
  c.fill(-1);
  a.fill(9, 60);  // the tail only
  c.copy_from(a, 32, 32, 0);
  const auto av = a.read(), cv = c.read();
  for (int i = 0; i < 64; ++i) EXPECT_EQ(av[i], i < 60 ? 7 : 9) << i;
  for (int i = 0; i < 64; ++i) EXPECT_EQ(cv[i], i < 32 ? (i + 32 < 60 ? 7 : 9) : -1) << i;
}

TEST(Buffer, OutOfRangeCopiesAreErrorsNamingTheRange) {
  const Device d = test::test_device();
  Buffer<float> b(d, 10);
  std::vector<float> big(11);
  try {
    b.write(big);
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_STREQ(e.what(), "Buffer<float>::write: elements [0, 11) are outside the buffer of 10 elements");
  }
  std::vector<float> out(4);
  EXPECT_THROW(b.read(out.data(), 4, 7), InvalidArgument);
  EXPECT_THROW(b.fill(0.f, 11), InvalidArgument);
  EXPECT_THROW(b.fill(0.f, 5, 6), InvalidArgument);
  Buffer<float> small(d, 4);
  EXPECT_THROW(small.copy_from(b, 5), InvalidArgument);
  EXPECT_THROW(b.copy_from(small, 4, 1), InvalidArgument);
  // Offset overflow must not wrap around.
  EXPECT_THROW(b.read(out.data(), 1, static_cast<std::size_t>(-1)), InvalidArgument);
  // In-range edge cases are fine.
  b.read(out.data(), 0, 10);
  b.write(big.data(), 10);
}

TEST(Buffer, EmptyBufferHasNoDeviceMemory) {
  const Device d = test::test_device();
  Buffer<float> e(d, 0);
  EXPECT_TRUE(e.empty());
  EXPECT_TRUE(e.read().empty());
  e.fill(1.f);
  EXPECT_THROW(e.write(std::vector<float>(1)), InvalidArgument);
}

TEST(Buffer, AllocationLargerThanTheDeviceAllowsIsAClearError) {
  const Device d = test::test_device();
  const std::size_t too_many = d.info().max_allocation / sizeof(float) + 1;
  try {
    Buffer<float> b(d, too_many);
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("largest allocation"), std::string::npos) << e.what();
  }
}

}  // namespace relit
