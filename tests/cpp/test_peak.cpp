// The calibrated FMA peak (kernels/peak.cl, relit/verify/peak_reference.hpp): its chains never become subnormal
// (which would measure microcode assists instead of the FMA rate), and the kernel agrees with its host reference.
#include "test_support.hpp"

#include <relit/verify/peak_reference.hpp>

#include <cmath>
#include <vector>

namespace relit {

TEST(Peak, NoChainEverBecomesSubnormal) {
  const float c = reference::PeakKernel::kFactor;
  for (std::size_t gid = 0; gid < 64; ++gid)  // the kernel's chains depend on gid % 64
    for (unsigned chain = 0; chain < reference::kPeakChains; ++chain)
      for (unsigned lane = 0; lane < 16; ++lane) {
        const reference::PeakChain start = reference::peak_chain(gid, chain, lane);
        ASSERT_TRUE(std::isnormal(start.b)) << "item " << gid << ", chain " << chain << ", lane " << lane;
        // Step to the float fixed point (a few thousand steps): every value on the way must be normal.
        bool all_normal = true;
        const float end = reference::peak_steps(start, c, 1000000, [&](float a) { all_normal &= std::isnormal(a); });
        ASSERT_TRUE(all_normal) << "item " << gid << ", chain " << chain << ", lane " << lane;
        EXPECT_EQ(std::fma(end, c, start.b), end)
            << "no fixed point: item " << gid << ", chain " << chain << ", lane " << lane;
      }
}

TEST(Peak, KernelsMatchTheHostReferenceBeyondTheFixedPoint) {
  const Device device = test::test_device();
  for (const auto& [name, lanes] : reference::kPeakKernels) {
    const std::size_t items = 128;
    Buffer<float> out(device, items);
    reference::PeakKernel peak(device, name, lanes, items);
    // 200,000 steps: past every chain's fixed point (at most 64 at the smallest sizes: Oclgrind runs each FMA alone).
    const std::vector<std::uint32_t> steps =
        test::tiny_sizes() ? std::vector<std::uint32_t>{1, 64} : std::vector<std::uint32_t>{1, 1000, 200000};
    for (const std::uint32_t iters : steps) {
      peak.iters = iters;
      out.fill(-1.0f);
      peak.launch(device, out);
      EXPECT_LE(peak.verify(out, items), 1.0) << name << ", " << iters << " steps";
    }
    out.fill(-1.0f);  // a result never written must fail the check
    EXPECT_GT(peak.verify(out, items), 1.0) << name;
  }
}

}  // namespace relit
