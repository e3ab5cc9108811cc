// The method registry: the run config's "method" key → the model class.
#include <relit/error.hpp>
#include <relit/method/bi.hpp>
#include <relit/method/nerv.hpp>

namespace relit::method {

std::vector<std::string> method_names() { return {"ours", "ours_brdf", "bi", "nerv"}; }

std::unique_ptr<Model> create_model(const Device& device, const std::string& method, const Json& config,
                                    const std::string& pointer) {
  if (method == "ours") return std::make_unique<Ours>(device, config, pointer);
  if (method == "ours_brdf") return std::make_unique<OursBrdf>(device, config, pointer);
  if (method == "bi") return std::make_unique<NeuralReflectanceField>(device, config, pointer);
  if (method == "nerv") return std::make_unique<NeRV>(device, config, pointer);
  std::string names;
  for (const auto& m : method_names()) names += (names.empty() ? "" : ", ") + m;
  throw ConfigError("/method", "unknown method '" + method + "'; valid methods: " + names);
}

void describe_model(const std::string& method, config::Docs& docs) {
  if (method == "ours") return Ours::describe(docs);
  if (method == "ours_brdf") return OursBrdf::describe(docs);
  if (method == "bi") return NeuralReflectanceField::describe(docs);
  if (method == "nerv") return NeRV::describe(docs);
  throw InvalidArgument("describe_model: unknown method '" + method + "'");
}

}  // namespace relit::method
