// A model's tensors in a checkpoint, and building a model from a run's checkpoint.
#include <relit/method/model_io.hpp>

#include <cmath>

namespace relit::method {

void put_tensor(io::Checkpoint& c, const std::string& name, const Buffer<float>& b) { c.tensors[name] = b.read(); }

void get_tensor(const io::Checkpoint& c, const std::string& name, Buffer<float>& b, const std::string& path) {
  auto it = c.tensors.find(name);
  if (it == c.tensors.end()) throw IOError(path + ": checkpoint has no tensor '" + name + "'");
  if (it->second.size() != b.size())
    throw IOError(path + ": tensor '" + name + "' has " + std::to_string(it->second.size()) +
                  " values, the model needs " + std::to_string(b.size()) + " (a checkpoint of another config?)");
  std::size_t bad = 0;
  for (float v : it->second) bad += !std::isfinite(v);
  if (bad)
    throw IOError(path + ": tensor '" + name + "' holds " + std::to_string(bad) + " NaN or infinite value(s) of " +
                  std::to_string(it->second.size()) + "; the run diverged or the file was altered");
  b.write(it->second);
}

void put_model(io::Checkpoint& c, const Model& model) {
  put_tensor(c, "theta", model.params());
  put_tensor(c, "psi", model.vis_params());
  put_tensor(c, "density_grid", model.density_grid().sigma);
}

void get_model(const io::Checkpoint& c, Model& model, const std::string& path) {
  get_tensor(c, "theta", model.params(), path);
  get_tensor(c, "psi", model.vis_params(), path);
  get_tensor(c, "density_grid", model.density_grid().sigma, path);
}

std::unique_ptr<Model> load_model(const Device& device, const std::string& path) {
  const io::Checkpoint c = io::load_checkpoint(path);
  if (!c.header.contains("config") || !c.header["config"].is_object() || !c.header["config"].contains("model"))
    throw IOError(path + ": not a relit run checkpoint (no model config in its header)");
  const Json& method_json = c.header["config"].contains("method") ? c.header["config"]["method"] : Json("ours");
  if (!method_json.is_string()) throw IOError(path + ": the method in its header is not a name");
  const std::string method = method_json.get<std::string>();
  auto model = create_model(device, method, c.header["config"]["model"], "/model");
  get_model(c, *model, path);
  return model;
}

}  // namespace relit::method
