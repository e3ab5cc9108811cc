// A model's tensors in a checkpoint, and building a model from a run's checkpoint.
#include <relit/method/model_io.hpp>

namespace relit::method {

void put_tensor(io::Checkpoint& c, const std::string& name, const Buffer<float>& b) { c.tensors[name] = b.read(); }

void get_tensor(const io::Checkpoint& c, const std::string& name, Buffer<float>& b, const std::string& path) {
  auto it = c.tensors.find(name);
  if (it == c.tensors.end()) throw IOError(path + ": checkpoint has no tensor '" + name + "'");
  if (it->second.size() != b.size())
    throw IOError(path + ": tensor '" + name + "' has " + std::to_string(it->second.size()) +
                  " values, the model needs " + std::to_string(b.size()) + " (a checkpoint of another config?)");
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
  if (!c.header.contains("config") || !c.header["config"].contains("model"))
    throw IOError(path + ": not a relit run checkpoint (no model config in its header)");
  const std::string method = c.header["config"].value("method", "ours");
  auto model = create_model(device, method, c.header["config"]["model"], "/model");
  get_model(c, *model, path);
  return model;
}

}  // namespace relit::method
