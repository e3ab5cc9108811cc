// The first test of the suite: every program in kernels/ (and the tests' own, tests/kernels) builds on every
// device under test.
// CTest makes every other test depend on this one, so a machine without OpenCL fails the suite.
#include "test_support.hpp"

namespace relit {

TEST(KernelsBuild, EveryProgramOnEverySelectedDevice) {
  const auto devices = test::devices_under_test();  // throws DeviceError when there is no device
  ASSERT_FALSE(devices.empty());
  for (const auto& device : devices) {
    const auto checks = check_programs(device);
    ASSERT_FALSE(checks.empty()) << "no embedded kernel programs";
    for (const auto& c : checks) {
      EXPECT_TRUE(c.ok) << c.file << " on " << device.info().description() << ":\n" << c.error;
      std::cout << "[ built    ] " << c.file << " on " << device.info().name << " in " << c.seconds << " s\n";
    }
  }
}

}  // namespace relit
