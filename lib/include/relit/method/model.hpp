// Model: what every method of relit (docs/design.md §4.3-4.5) gives the trainer and the renderer of images.
//
// A method owns its networks and two flat parameter buffers — θ (everything the render loss trains) and ψ
// (the visibility network, trained only against marches through the learned density) — with a cached density
// grid for those marches. A pass renders a batch of rays; backward() turns dL/dcolour into dL/dθ, and
// train_visibility() writes dL/dψ. The run config's "method" key picks the method from the registry
// (methods()), where each method's source registers it (RELIT_REGISTER_METHODS, docs/method.md):
//
//   "ours"  Ours (relit/method/ours.hpp)                  "bi"    NeuralReflectanceField (relit/method/bi.hpp)
//   "ours_brdf"  OursBrdf (relit/method/ours.hpp)         "nerv"  NeRV (relit/method/nerv.hpp)
//
//   auto model = relit::method::create_model(device, "bi", config["model"]);
//   auto pass = model->make_pass();
//   model->render(*pass, rays, n, {.training = true, ...});
//   model->backward(*pass, rays, {&d_fine}, options);
#pragma once

#include <relit/parallel.hpp>
#include <relit/cl/buffer.hpp>
#include <relit/config.hpp>
#include <relit/nn/loss.hpp>
#include <relit/render/visibility.hpp>

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace relit::render {
class EnvironmentSamples;
}

namespace relit::method {

/// Per-stage timing of a training step, for profiling: when enabled, mark() waits for the device and adds the
/// time since the previous mark to `stage`. Disabled (the default) it does nothing, so steps stay asynchronous.
class StageTimer {
 public:
  void enable(const Device& device);
  bool enabled() const { return m_enabled; }
  void start();
  void mark(const std::string& stage);
  /// Seconds per stage, in first-marked order.
  const std::vector<std::pair<std::string, double>>& seconds() const { return m_seconds; }
  void clear() { m_seconds.clear(); }

 private:
  bool m_enabled = false;
  Device m_device;
  double m_last = 0;
  std::vector<std::pair<std::string, double>> m_seconds;
};

/// Scratch of one pass over a batch of rays (each method derives its own); reused across iterations.
class ModelPass {
 public:
  virtual ~ModelPass() = default;
  std::uint32_t n_rays = 0;
  parallel::Share share;  ///< which rays of the global batch this pass holds (PassOptions::share of render())
};

/// How a pass runs.
struct PassOptions {
  bool training = false;          ///< jitter the samples and keep what backward() needs
  std::uint32_t seed = 0;         ///< the run's seed: draws the per-iteration random directions
  std::uint32_t iteration = 0;    ///< training step, or tile index when rendering an image
  std::uint32_t jitter_seed = 0;  ///< seeds the sample jitter of this pass (training)
  bool march_visibility = false;  ///< visibility by marching the density grid instead of the network
  /// The environment directions of this pass (EnvironmentSamples::draw()) for a model trained with an
  /// environment; null renders under the point light alone.
  const render::EnvironmentSamples* env = nullptr;
  StageTimer* timer = nullptr;
  /// Data parallelism (relit/parallel.hpp): the pass's rays are rays share.first, share.first + share.stride, ...
  /// of a global batch of `batch_rays` rays (0: the pass's own n_rays, one process). The sample jitter and the
  /// visibility net's training subset follow the global ray index, so the ranks' passes together are the
  /// single-process pass.
  parallel::Share share;
  std::uint32_t batch_rays = 0;
};

class Model {
 public:
  virtual ~Model() = default;

  /// The run config's name of the method ("ours", "bi", "nerv").
  virtual std::string method() const = 0;
  /// The resolved "model" config: building from it gives the same model.
  const Json& hyperparams() const { return m_resolved; }
  const Device& device() const { return m_device; }

  std::uint32_t n_params() const { return static_cast<std::uint32_t>(m_params.size()); }
  std::uint32_t n_vis_params() const { return static_cast<std::uint32_t>(m_vis_params.size()); }
  Buffer<float>& params() { return m_params; }
  Buffer<float>& vis_params() { return m_vis_params; }
  const Buffer<float>& params() const { return m_params; }
  const Buffer<float>& vis_params() const { return m_vis_params; }
  Buffer<float>& grads() { return m_grads; }
  Buffer<float>& vis_grads() { return m_vis_grads; }
  /// Re-initialises both parameter buffers deterministically from `seed`.
  virtual void initialize(std::uint64_t seed) = 0;

  /// Re-evaluates the density grid of the visibility targets from the current θ. With a `share` of several ranks
  /// (relit/parallel.hpp), only rank share.first's contiguous 1/share.stride of the voxels, the others set to 0:
  /// the sum of the ranks' grids is the whole grid (Trainer sums them).
  virtual void refresh_density_grid(parallel::Share share = {}) = 0;
  /// Training steps between density-grid refreshes.
  virtual std::uint32_t grid_refresh_every() const = 0;
  const render::DensityGrid& density_grid() const { return m_grid; }
  render::DensityGrid& density_grid() { return m_grid; }

  /// The model was trained with an environment light ('env+point' data), and its N_e when rendering and
  /// per training step.
  virtual bool has_environment() const = 0;
  virtual std::uint32_t env_dirs() const = 0;
  virtual std::uint32_t env_dirs_training() const = 0;
  /// "network" or "march": the visibility used when rendering unless told otherwise.
  virtual std::string inference_visibility() const = 0;
  /// Network queries per camera ray (sizes render tiles).
  virtual std::uint32_t queries_per_ray() const = 0;

  virtual std::unique_ptr<ModelPass> make_pass() const = 0;
  /// Renders `n_rays` rays (records of render/volume_renderer.hpp; t_near/t_far are written).
  virtual void render(ModelPass& pass, Buffer<float>& rays, std::uint32_t n_rays, const PassOptions& options) const = 0;
  /// The images a pass renders and the render loss compares with the target (Bi et al.: coarse and fine);
  /// the last is the model's image.
  virtual std::uint32_t n_colors() const { return 1; }
  /// Colour `i` of the last pass, n_rays x 3 rows (linear RGB).
  virtual const Buffer<float>& color(const ModelPass& pass, std::uint32_t i) const = 0;
  /// The transmittance of the last pass's rays through the model's image (the last colour's samples): n_rays
  /// values, 1 - the pixel's alpha.
  virtual const Buffer<float>& transmittance(const ModelPass& pass) const = 0;
  /// Given dL/dcolour i (n_rays x 3 rows) for every colour: writes dL/dθ into grads() (overwriting). ψ gets
  /// nothing (gradient isolation). `options` as given to the training render().
  virtual void backward(ModelPass& pass, const Buffer<float>& rays, const std::vector<const Buffer<float>*>& d_colors,
                        const PassOptions& options) = 0;
  /// The visibility loss of the last training pass against density-grid marches (constants, so θ gets
  /// nothing): writes dL/dψ into vis_grads() (overwriting) and the mean loss into `value` (on the device).
  /// Returns the fraction of the global batch's visibility queries this pass trained on (1 in one process):
  /// the loss and dL/dψ are this pass's mean times that fraction, so the ranks' results add up to the global ones.
  virtual double train_visibility(ModelPass& pass, const Buffer<float>& rays, const nn::Loss& loss,
                                  Buffer<float>& value, float weight, const PassOptions& options) = 0;

 protected:
  Model() = default;
  explicit Model(const Device& device) : m_device(device) {}
  /// Allocates θ, ψ (and their gradients, zeroed) and a cubic density grid.
  void allocate_storage(std::uint32_t n_theta, std::uint32_t n_psi, std::uint32_t grid_resolution);
  Device m_device;
  Json m_resolved;
  Buffer<float> m_params, m_grads, m_vis_params, m_vis_grads;
  render::DensityGrid m_grid;
};

/// A method as the registry knows it: its name in run configs, its factory and the documentation of its
/// "model" config.
struct MethodEntry {
  using Factory = std::function<std::unique_ptr<Model>(const Device&, const Json& config, const std::string& pointer)>;
  std::string name;
  /// Where the method is listed in method_names() (and in docs/config.md): by rank, then by name.
  int rank = 0;
  /// What the method is, in a few words (the run config's "method" key lists them).
  std::string summary;
  Factory create;
  /// Appends every key of the method's "model" config, per JSON object (pointers "/model...").
  std::function<void(config::Docs&)> describe;
  /// Reads a "model" config (at `pointer`) as create() does, without a device: ConfigErrors for bad keys and
  /// values; returns the resolved config.
  std::function<Json(const Json& config, const std::string& pointer)> check;
};

/// The methods a run config may name. Each method's source adds its entries in a registration function
/// (RELIT_REGISTER_METHODS(name) in lib/src/method/registration.hpp), which the library calls on first use.
class MethodRegistry {
 public:
  void add(MethodEntry entry);
  /// Registers class M: constructible as M(device, config, pointer), with static M::describe(config::Docs&)
  /// and static M::check(config, pointer).
  template <class M>
  void add(const std::string& name, int rank, const std::string& summary) {
    add({name, rank, summary,
         [](const Device& device, const Json& config, const std::string& pointer) -> std::unique_ptr<Model> {
           return std::make_unique<M>(device, config, pointer);
         },
         [](config::Docs& docs) { M::describe(docs); },
         [](const Json& config, const std::string& pointer) { return M::check(config, pointer); }});
  }
  /// The entry of `name`, or null.
  const MethodEntry* find(const std::string& name) const;
  /// Every method, in listing order.
  const std::vector<MethodEntry>& entries() const { return m_entries; }

 private:
  std::vector<MethodEntry> m_entries;
};

/// The registry of the methods (filled on first use).
const MethodRegistry& methods();

/// The methods a run config may name.
std::vector<std::string> method_names();
/// Builds method `method`'s model from its "model" config object (at JSON pointer `pointer`).
std::unique_ptr<Model> create_model(const Device& device, const std::string& method, const Json& config,
                                    const std::string& pointer = "/model");
/// Every key of method `method`'s model config (for docs/config.md).
void describe_model(const std::string& method, config::Docs& docs);
/// Reads method `method`'s "model" config as create_model() does, without a device; returns it resolved.
Json check_model_config(const std::string& method, const Json& config, const std::string& pointer = "/model");

}  // namespace relit::method
