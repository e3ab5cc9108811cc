// Ours and Ours + BRDF: MediumModels of their parts, and their registration.
#include <relit/method/ours.hpp>

#include "registration.hpp"

namespace relit::method {

Ours::Ours(const Device& device, const Json& config, const std::string& pointer) : MediumModel(device, method_parts()) {
  build(config, pointer);
}

void Ours::describe(config::Docs& docs) { Ours().describe_keys(docs); }

OursBrdf::OursBrdf(const Device& device, const Json& config, const std::string& pointer)
    : MediumModel(device, method_parts()) {
  build(config, pointer);
}

void OursBrdf::describe(config::Docs& docs) { OursBrdf().describe_keys(docs); }

RELIT_REGISTER_METHODS(ours) {
  registry.add<Ours>("ours", 10, "Ours, the paper's method: docs/design.md §4.3");
  registry.add<OursBrdf>("ours_brdf", 20, "Ours + BRDF for solids: docs/design.md §4.4");
}

}  // namespace relit::method
