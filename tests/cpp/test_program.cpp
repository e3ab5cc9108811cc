// Programs and kernels: correctness of the utility kernels against double-precision references, the
// build cache, -D specialisation, RELIT_KERNEL_DIR, and build errors that carry the compiler's log.
#include "test_support.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>

namespace relit {

using test::ScopedEnv;
using test::TempDir;

namespace {
void write_file(const std::filesystem::path& p, const std::string& text) { std::ofstream(p) << text; }
}  // namespace

TEST(Program, AxpyMatchesDoubleReferenceOnRandomInputs) {
  for (const Device& d : test::devices_under_test()) {
    for (const unsigned n : {1u, 37u, 1000u, 4099u}) {  // not multiples of the local size
      std::mt19937 rng(n);
      std::uniform_real_distribution<float> u(-10.f, 10.f);
      std::vector<float> x(n), y(n);
      for (auto& v : x) v = u(rng);
      for (auto& v : y) v = u(rng);
      const float a = u(rng);
      Buffer<float> bx(d, x), by(d, y);
      d.kernel("util.cl", "axpy_f32").args(n, a, bx, by).launch(n, 64);
      const auto got = by.read();
      const Eigen::VectorXd ref = double(a) * Eigen::Map<Eigen::VectorXf>(x.data(), n).cast<double>() +
                                  Eigen::Map<Eigen::VectorXf>(y.data(), n).cast<double>();
      for (unsigned i = 0; i < n; ++i)
        EXPECT_NEAR(got[i], ref[i], 1e-6 * (1 + std::abs(ref[i]))) << "n=" << n << " i=" << i;
    }
  }
}

TEST(Program, FillUniformIsReproducibleAndInRange) {
  const Device d = test::test_device();
  const unsigned n = 100000;
  Buffer<float> a(d, n), b(d, n);
  d.kernel("fill_uniform.cl", "fill_uniform_f32").args(n, 42u, -2.f, 3.f, a).launch(n, 64);
  d.kernel("fill_uniform.cl", "fill_uniform_f32").args(n, 42u, -2.f, 3.f, b).launch(n, 256);  // other launch shape
  const auto av = a.read(), bv = b.read();
  EXPECT_EQ(av, bv);
  double mean = 0;
  for (float v : av) {
    ASSERT_GE(v, -2.f);
    ASSERT_LT(v, 3.f);
    mean += v;
  }
  EXPECT_NEAR(mean / n, 0.5, 0.02);  // 5 sigma of a U(-2,3) mean over 1e5 samples is 0.023
}

TEST(Program, AddedSourcesBuildWithRelitsHeadersAndTheirNamesAreChecked) {
  const std::string text =
      "#include \"common.clh\"\n__kernel void k(__global uint* out) { out[0] = 7u + relit_hash(0u) * 0u; }\n";
  add_kernel_source("relit_test_added.cl", text);
  EXPECT_NO_THROW(add_kernel_source("relit_test_added.cl", text));  // the same text again
  EXPECT_THROW(add_kernel_source("relit_test_added.cl", text + "\n"), InvalidArgument);
  EXPECT_THROW(add_kernel_source("util.cl", text), InvalidArgument);  // relit ships it
  EXPECT_THROW(add_kernel_source("sub/x.cl", text), InvalidArgument);
  EXPECT_THROW(add_kernel_source("x.txt", text), InvalidArgument);
  const Device d = test::test_device();
  Buffer<unsigned> out(d, 1);
  d.kernel("relit_test_added.cl", "k").args(out).launch(1);
  EXPECT_EQ(out.read()[0], 7u);
  std::vector<std::string> files;
  for (const auto& c : check_programs(d)) files.push_back(c.file);
  EXPECT_NE(std::find(files.begin(), files.end(), "relit_test_added.cl"), files.end());
  EXPECT_NE(std::find(files.begin(), files.end(), "pathtrace_probe.cl"), files.end());  // tests/kernels
  EXPECT_NE(std::find(files.begin(), files.end(), "util.cl"), files.end());
}

TEST(Program, CacheIsKeyedBySourceAndOptions) {
  const Device d = test::test_device();
  d.program("util.cl");
  const auto before = d.cached_programs();
  d.program("util.cl");
  EXPECT_EQ(d.cached_programs(), before);
  d.program("util.cl", {{"RELIT_TEST_UNUSED", "1"}});
  EXPECT_EQ(d.cached_programs(), before + 1);
  const auto p = d.program("util.cl", {{"RELIT_TEST_UNUSED", "1"}});
  EXPECT_EQ(d.cached_programs(), before + 1);
  EXPECT_NE(p.options().find("-DRELIT_TEST_UNUSED=1"), std::string::npos);
}

TEST(Program, DefinesSpecialiseTheBuild) {
  TempDir dir("defines");
  write_file(dir.path() / "spec.cl", "__kernel void k(__global int* out) { out[0] = VALUE * 2; }\n");
  ScopedEnv env("RELIT_KERNEL_DIR", dir.path().string());
  const Device d = test::test_device();
  Buffer<int> out(d, 1);
  d.kernel("spec.cl", "k", {{"VALUE", "21"}}).args(out).launch(1);
  EXPECT_EQ(out.read()[0], 42);
  d.kernel("spec.cl", "k", {{"VALUE", "5"}}).args(out).launch(1);
  EXPECT_EQ(out.read()[0], 10);
  EXPECT_THROW(d.program("spec.cl", {{"BAD NAME", "1"}}), InvalidArgument);
}

TEST(Program, KernelDirOverridesEmbeddedSourcesAndResolvesIncludes) {
  TempDir dir("kdir");
  write_file(dir.path() / "consts.clh", "#define RELIT_TEST_CONST 1234\n");
  write_file(dir.path() / "inc.cl",
             "#include \"consts.clh\"\n#include \"consts.clh\"\n#include \"common.clh\"\n"
             "__kernel void k(__global uint* out) { out[0] = RELIT_TEST_CONST + relit_hash(0u) * 0u; }\n");
  ScopedEnv env("RELIT_KERNEL_DIR", dir.path().string());
  const Device d = test::test_device();
  Buffer<unsigned> out(d, 1);
  d.kernel("inc.cl", "k").args(out).launch(1);  // common.clh comes from the embedded copy
  EXPECT_EQ(out.read()[0], 1234u);
}

TEST(Program, SyntaxErrorGivesBuildErrorWithLogOptionsAndSavedSource) {
  TempDir dir("broken");
  write_file(dir.path() / "broken.cl", "__kernel void k(__global float* x) {\n  x[0] = 1.0f +;\n}\n");
  ScopedEnv env("RELIT_KERNEL_DIR", dir.path().string());
  const Device d = test::test_device();
  try {
    d.program("broken.cl", {{"WIDTH", "64"}});
    FAIL() << "expected BuildError";
  } catch (const BuildError& e) {
    const std::string m = e.what();
    EXPECT_EQ(e.program(), "broken.cl");
    EXPECT_NE(m.find("failed to build on " + d.info().name), std::string::npos) << m;
    EXPECT_NE(e.options().find("-DWIDTH=64"), std::string::npos);
    EXPECT_NE(m.find("-DWIDTH=64"), std::string::npos) << m;
    EXPECT_NE(e.log().find("broken.cl:2"), std::string::npos) << "the log should point at line 2:\n" << e.log();
    ASSERT_TRUE(std::filesystem::exists(e.source_path())) << e.source_path();
    std::ifstream saved(e.source_path());
    const std::string text((std::istreambuf_iterator<char>(saved)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("1.0f +;"), std::string::npos);
    EXPECT_NE(m.find(e.source_path()), std::string::npos);
  }
}

TEST(Program, MissingSourceAndUnknownKernelAreClearErrors) {
  const Device d = test::test_device();
  try {
    d.program("no_such_file.cl");
    FAIL() << "expected IOError";
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find("no kernel source 'no_such_file.cl'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("util.cl"), std::string::npos) << "should list the sources: " << e.what();
  }
  try {
    d.program("util.cl").kernel("no_such_kernel");
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("axpy_f32"), std::string::npos) << e.what();
  }
}

TEST(Program, KernelNamesAndWorkGroupQueries) {
  const Device d = test::test_device();
  const auto names = d.program("util.cl").kernel_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "axpy_f32"), names.end());
  const Kernel k = d.kernel("util.cl", "axpy_f32");
  EXPECT_GT(k.max_work_group_size(), 0u);
  EXPECT_GT(k.preferred_work_group_multiple(), 0u);
  EXPECT_EQ(round_up(65, 64), 128u);
  EXPECT_EQ(round_up(64, 64), 64u);
  EXPECT_EQ(round_up(7, 0), 7u);
}

}  // namespace relit
