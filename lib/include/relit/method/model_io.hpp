// A model in a checkpoint: its tensors (θ, ψ, the density grid) and building a model back from a run's
// checkpoint, with no dataset (docs/renderer.md, "Checkpoints"). The trainer adds its optimisers' state and
// step to the same file.
//
//   auto model = relit::method::load_model(device, "runs/cloud/checkpoint.relit");
//   relit::Image img = relit::method::render_image(*model, camera, light);
#pragma once

#include <relit/io/checkpoint.hpp>
#include <relit/method/model.hpp>

#include <memory>
#include <string>

namespace relit::method {

/// Stores `buffer`'s values as tensor `name`.
void put_tensor(io::Checkpoint& checkpoint, const std::string& name, const Buffer<float>& buffer);
/// Loads tensor `name` into `buffer`; IOError naming `path` when it is missing or of another size.
void get_tensor(const io::Checkpoint& checkpoint, const std::string& name, Buffer<float>& buffer,
                const std::string& path);

/// The model's tensors: "theta", "psi" and "density_grid".
void put_model(io::Checkpoint& checkpoint, const Model& model);
void get_model(const io::Checkpoint& checkpoint, Model& model, const std::string& path);

/// Builds the model stored in a checkpoint (its config and parameters; the dataset is not needed).
std::unique_ptr<Model> load_model(const Device& device, const std::string& checkpoint_path);

}  // namespace relit::method
