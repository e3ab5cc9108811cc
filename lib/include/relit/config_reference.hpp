// The configuration reference (docs/config.md), generated from the registries that parse configs, so the
// documentation cannot drift from the code: every component is built once from an empty config and its
// Reader reports each key it read with type, default, valid values and description.
#pragma once

#include <string>

namespace relit {

/// The whole reference as Markdown. Throws if a component cannot be built from its defaults.
std::string config_reference_markdown();

}  // namespace relit
