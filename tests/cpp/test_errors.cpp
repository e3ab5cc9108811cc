// Error types and messages.
#include "test_support.hpp"

namespace relit {

TEST(Errors, ClErrorNamesCallCodeAndLocation) {
  try {
    RELIT_CL_CHECK(-5);
    FAIL() << "expected ClError";
  } catch (const ClError& e) {
    const std::string m = e.what();
    EXPECT_EQ(e.code(), -5);
    EXPECT_NE(m.find("CL_OUT_OF_RESOURCES (-5)"), std::string::npos) << m;
    EXPECT_NE(m.find("in -5"), std::string::npos) << m;
    EXPECT_NE(m.find("tests/cpp/test_errors.cpp:"), std::string::npos) << "relative file:line: " << m;
  }
}

TEST(Errors, KernelArgumentErrorsNameTheKernelAndArgument) {
  const Device d = test::test_device();
  Kernel k = d.kernel("util.cl", "axpy_f32");
  try {
    k.arg(9, 1.0f);
    FAIL() << "expected ClError";
  } catch (const ClError& e) {
    EXPECT_NE(std::string(e.what()).find("clSetKernelArg(axpy_f32, arg 9)"), std::string::npos) << e.what();
  }
}

TEST(Errors, CodeNames) {
  EXPECT_STREQ(cl_error_name(0), "CL_SUCCESS");
  EXPECT_STREQ(cl_error_name(-11), "CL_BUILD_PROGRAM_FAILURE");
  EXPECT_STREQ(cl_error_name(-1001), "CL_PLATFORM_NOT_FOUND_KHR");
  EXPECT_STREQ(cl_error_name(12345), "CL_UNKNOWN_ERROR");
}

TEST(Errors, ConfigErrorCarriesPointer) {
  const ConfigError e("/network/n_neurons", "must be one of 16, 32, 64, 128, 256 (got 48)");
  EXPECT_EQ(e.pointer(), "/network/n_neurons");
  EXPECT_STREQ(e.what(), "/network/n_neurons: must be one of 16, 32, 64, 128, 256 (got 48)");
  const InvalidArgument& base = e;  // a ConfigError is an InvalidArgument is an Error
  EXPECT_NE(dynamic_cast<const Error*>(&base), nullptr);
}

TEST(Errors, LogLevelsParse) {
  EXPECT_EQ(parse_log_level("DEBUG"), LogLevel::Debug);
  EXPECT_EQ(parse_log_level("warn"), LogLevel::Warning);
  EXPECT_EQ(parse_log_level("off"), LogLevel::Off);
  EXPECT_THROW(parse_log_level("loud"), InvalidArgument);
  std::vector<std::string> seen;
  set_log_sink([&](LogLevel, const std::string& m) { seen.push_back(m); });
  const LogLevel old = log_level();
  set_log_level(LogLevel::Info);
  log_debug("hidden");
  log_info("shown");
  set_log_level(old);
  set_log_sink(nullptr);
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0], "shown");
}

}  // namespace relit
