// docs/config.md is generated from the registries; this test fails when the committed copy is stale.
#include "test_support.hpp"

#include <relit/config_reference.hpp>

#include <fstream>
#include <sstream>

namespace relit {

TEST(ConfigReference, CommittedDocsAreUpToDate) {
  const std::string generated = config_reference_markdown();
  std::ifstream in(std::string(RELIT_SOURCE_DIR) + "/docs/config.md", std::ios::binary);
  ASSERT_TRUE(in) << "docs/config.md is missing: run `relit config-reference -o docs/config.md`";
  std::ostringstream committed;
  committed << in.rdbuf();
  EXPECT_TRUE(committed.str() == generated)
      << "docs/config.md is stale: regenerate it with `build/apps/relit config-reference -o docs/config.md`";
}

TEST(ConfigReference, ListsEveryRegisteredComponent) {
  const std::string text = config_reference_markdown();
  for (const char* s : {"## Losses", "### `L2`", "### `RelativeL2`", "### `ToneMappedL2`", "### `Adam`",
                        "| `learning_rate` | float | `0.01` |", "## Encodings", "## Networks"})
    EXPECT_NE(text.find(s), std::string::npos) << s;
}

}  // namespace relit
