// Device enumeration and selection: by index, platform:device, name fragment, RELIT_DEVICE, no match.
#include "test_support.hpp"

#include <algorithm>
#include <cctype>

namespace relit {

using test::ScopedEnv;

namespace {
std::string upper(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::toupper(c); });
  return s;
}
}  // namespace

TEST(Device, ListingHasConsistentIndicesAndCapabilities) {
  const auto infos = list_devices();
  ASSERT_FALSE(infos.empty());
  for (std::size_t i = 0; i < infos.size(); ++i) {
    EXPECT_EQ(infos[i].index, static_cast<int>(i));
    EXPECT_FALSE(infos[i].name.empty());
    EXPECT_GT(infos[i].compute_units, 0u);
    EXPECT_GT(infos[i].global_memory, 0u);
    EXPECT_GE(infos[i].global_memory, infos[i].max_allocation);
    EXPECT_GT(infos[i].max_work_group_size, 0u);
    EXPECT_TRUE(infos[i].type == "cpu" || infos[i].type == "gpu" || infos[i].type == "accelerator" ||
                infos[i].type == "other");
    EXPECT_NE(infos[i].description().find(infos[i].name), std::string::npos);
  }
}

TEST(Device, SelectByIndex) {
  ScopedEnv env("RELIT_DEVICE", std::nullopt);
  const auto infos = list_devices();
  const int last = infos.back().index;
  const Device d = Device::select(std::to_string(last));
  EXPECT_EQ(d.info().index, last);
  EXPECT_EQ(d.info().name, infos.back().name);
}

TEST(Device, SelectByPlatformAndDeviceIndices) {
  const auto info = list_devices().front();
  const Device d = Device::select(std::to_string(info.platform_index) + ":" + std::to_string(info.device_index));
  EXPECT_EQ(d.info().index, info.index);
}

TEST(Device, SelectByCaseInsensitiveNameFragment) {
  const auto info = list_devices().front();
  const std::string fragment = upper(info.name.substr(0, std::min<std::size_t>(info.name.size(), 6)));
  const Device d = Device::select(fragment);
  EXPECT_NE(upper(d.info().name + " " + d.info().platform_name).find(fragment), std::string::npos);
  // The device type also matches: "cpu" / "gpu".
  EXPECT_EQ(Device::select(info.type).info().type, info.type);
}

TEST(Device, SelectFromEnvironmentVariable) {
  const auto infos = list_devices();
  ScopedEnv env("RELIT_DEVICE", std::to_string(infos.back().index));
  EXPECT_EQ(Device::select().info().index, infos.back().index);
  // An explicit selector wins over the environment.
  EXPECT_EQ(Device::select("0").info().index, 0);
}

TEST(Device, NoMatchInEnvironmentNamesTheVariableAndListsDevices) {
  ScopedEnv env("RELIT_DEVICE", std::string("no-such-device-xyz"));
  try {
    Device::select();
    FAIL() << "expected DeviceError";
  } catch (const DeviceError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("RELIT_DEVICE='no-such-device-xyz' matches no OpenCL device"), std::string::npos) << m;
    EXPECT_NE(m.find(list_devices().front().name), std::string::npos) << "should list the devices: " << m;
  }
}

TEST(Device, NoMatchForIndexOutOfRange) {
  EXPECT_THROW(Device::select("999"), DeviceError);
  EXPECT_THROW(Device::select("0:999"), DeviceError);
  EXPECT_THROW(Device::select_all("no-such-device-xyz"), DeviceError);
}

TEST(Device, DefaultPrefersGpuElseFirstDevice) {
  ScopedEnv env("RELIT_DEVICE", std::nullopt);
  const auto infos = list_devices();
  const auto gpu = std::find_if(infos.begin(), infos.end(), [](const DeviceInfo& i) { return i.type == "gpu"; });
  const int expected = gpu != infos.end() ? gpu->index : 0;
  EXPECT_EQ(Device::select().info().index, expected);
}

TEST(Device, SameDeviceSharesContextAndProgramCache) {
  const Device a = Device::select("0");
  const Device b = Device::select("0");
  EXPECT_TRUE(a == b);
  EXPECT_EQ(a.context()(), b.context()());
  a.program("util.cl");
  const std::size_t cached = b.cached_programs();
  EXPECT_GE(cached, 1u);
  b.program("util.cl");  // a cache hit: no new entry
  EXPECT_EQ(a.cached_programs(), cached);
}

TEST(Device, SelectAllMatchesEverything) { EXPECT_EQ(Device::select_all("all").size(), list_devices().size()); }

TEST(Device, EmptyHandleIsAnError) {
  Device d;
  EXPECT_FALSE(d.valid());
  EXPECT_THROW(d.info(), InvalidArgument);
}

}  // namespace relit
