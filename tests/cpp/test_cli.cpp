// The command line in process: its progress text and its error boundary (every bad argument is a clear error
// with a non-zero exit code, whatever the kind of failure underneath).
#include "test_support.hpp"

#include "cli.hpp"
#include "progress_bar.hpp"

#include <gtest/gtest.h>

#include <iostream>
#include <sstream>

namespace relit {
namespace {

TEST(Cli, SlowRatesAreShownAsSecondsPerItem) {
  using cli::ProgressBar;
  EXPECT_EQ(ProgressBar::rate(0.25, "views"), "4.00 s/view");
  EXPECT_EQ(ProgressBar::rate(0.02, "views"), "50.0 s/view");
  EXPECT_EQ(ProgressBar::rate(1234, "samples"), "1.2k samples/s");
  EXPECT_EQ(ProgressBar::rate(3, "steps"), "3.0 steps/s");
  EXPECT_EQ(ProgressBar::rate(1.44, "views"), "1.4 views/s");
  EXPECT_EQ(ProgressBar::rate(42, "steps"), "42 steps/s");
  EXPECT_EQ(ProgressBar::rate(0, "steps"), "- steps/s");
}

// Runs the command line with stderr captured.
std::pair<int, std::string> run(const std::vector<std::string>& args) {
  std::ostringstream err;
  auto* old = std::cerr.rdbuf(err.rdbuf());
  std::vector<std::string> argv{"relit"};
  argv.insert(argv.end(), args.begin(), args.end());
  const int code = cli::run(argv);
  std::cerr.rdbuf(old);
  return {code, err.str()};
}

TEST(Cli, BadArgumentsAreClearErrorsWithNonZeroExits) {
  test::TempDir dir("cli");
  const std::string file = (dir.path() / "a_file").string();
  io::write_file_atomic(file, "precious");
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"frobnicate"}, "unknown command 'frobnicate'"},
      {{"train", "ds", "--steps", "-5", "--out", "r"}, "must be an integer in [0, "},
      {{"train", "ds", "--steps", "1e3", "--out", "r"}, "must be an integer"},
      {{"train", "ds", "--seed", "4294967296", "--out", "r"}, "must be an integer in [0, 4294967295]"},
      {{"train", "ds", "--minutes", "nan", "--out", "r"}, "must be a finite number"},
      {{"train", "ds", "--out", file}, "is an existing file"},
      {{"train", "ds", "--out", file + "/run"}, "Not a directory"},
      {{"render", "run", "--out", "a.png", "--resolution", "0"}, "[1, 16384]"},
      {{"render", "run", "--out", "a.png", "--spp", "4294967295"}, "[1, 65536]"},
      {{"generate", "--out", "x", "--resolution", "100000"}, "[4, 4096]"},
      {{"generate", "--out", file, "--overwrite"}, "is a file"},
      {{"bench", "--compare", file, file}, "is not valid JSON"},
  };
  for (const auto& [args, expected] : cases) {
    const auto [code, err] = run(args);
    EXPECT_NE(code, 0) << args[0];
    EXPECT_NE(err.find(expected), std::string::npos)
        << "relit " << args[0] << " ...: expected '" << expected << "', got: " << err;
  }
  EXPECT_EQ(io::read_file(file), "precious");
}

TEST(Cli, AnUnknownLogLevelInTheEnvironmentIsAnError) {
  test::ScopedEnv env("RELIT_LOG", std::string("bogus"));
  const auto [code, err] = run({"config-reference"});
  EXPECT_NE(code, 0);
  EXPECT_NE(err.find("RELIT_LOG='bogus'"), std::string::npos) << err;
}

}  // namespace
}  // namespace relit
