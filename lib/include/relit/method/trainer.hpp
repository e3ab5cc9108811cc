// Training and relighting with the "Ours" model (DESIGN §4.3, §7).
//
//   auto config = relit::method::preset("fast");                       // or a JSON file's contents
//   relit::method::Trainer trainer(device, "data/cloud", config);
//   trainer.set_output("runs/cloud");                                  // config.json, log.jsonl, checkpoints
//   trainer.run(3000, [](const TrainStats& s) { ...; return true; });  // every log_every steps
//   relit::Image img = relit::method::render_image(trainer.model(), camera, light);
//
// A run config is {"method": "ours" | "bi" | "nerv", "model": {...}, "training": {...}}; docs/method.md describes it
// and docs/config.md lists every key. A step enqueues its work only (no host synchronisation) except at the periodic
// loss readback (log_every), validation and checkpoints.
#pragma once

#include <relit/method/model.hpp>
#include <relit/render/volume_renderer.hpp>
#include <relit/render/environment.hpp>
#include <relit/io/image.hpp>
#include <relit/nn/loss.hpp>
#include <relit/nn/optimizer.hpp>
#include <relit/progress.hpp>
#include <relit/render/rays.hpp>
#include <relit/scene/camera.hpp>
#include <relit/scene/light.hpp>

#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace relit::method {

/// The names of the preset configs ("fast", "paper", and per baseline "bi-fast", "nerv-paper", ...).
std::vector<std::string> preset_names();
/// A preset run config by name; throws InvalidArgument listing the presets for an unknown name.
Json preset(const std::string& name);
/// The preset or file to load for `spec` and a method: with a preset name ("fast", "paper") and a baseline
/// method ("bi", "nerv"), that method's preset ("bi-fast"); otherwise `spec` itself. Throws InvalidArgument
/// for an unknown method.
std::string config_for_method(const std::string& spec, const std::string& method);
/// Sets a run config's "method" to `method` (nothing when empty): a config that names another method is a
/// ConfigError naming `source` (where the config came from), an unknown method an InvalidArgument.
void set_method(Json& config, const std::string& method, const std::string& source);
/// `spec` is a preset name or the path of a JSON file; throws ConfigError/IOError naming the file on errors.
Json load_run_config(const std::string& spec);

/// Every key of a run config, object by object (the "Run config" part of docs/config.md).
config::Docs run_config_docs();

/// One split of a dataset on the host: cameras, lights and linear RGB images (n x h x w x 3).
struct DatasetSplit {
  std::string split;
  std::vector<std::string> names;  ///< file stems ("r_012")
  std::vector<Camera> cameras;
  std::vector<PointLight> lights;
  std::vector<float> images;
  int width = 0, height = 0;
  /// The environment light of an 'env+point' dataset (every view is lit by it as well), or null.
  std::shared_ptr<const EnvironmentLight> environment;
  std::size_t size() const { return cameras.size(); }
  /// View i's image (h x w x 3).
  std::vector<float> image(std::size_t i) const;
};

/// Reads a split of a dataset folder (docs/dataset-format.md). `max_views` > 0 keeps that many views,
/// spread evenly over the split. Throws IOError naming the folder/file when something is missing or corrupt.
DatasetSplit load_split(const std::string& dataset_dir, const std::string& split, std::size_t max_views = 0);

/// The environment light of an 'env+point' dataset folder, or null for 'point' data.
std::shared_ptr<const EnvironmentLight> dataset_environment(const std::string& dataset_dir);

/// The non-model keys of a run config's "training" object.
struct TrainingSettings {
  std::uint32_t batch_rays = 1200;
  std::uint32_t steps = 3000;
  std::uint32_t seed = 0;
  float visibility_loss_weight = 1.0f;
  std::uint32_t log_every = 50;
  std::uint32_t validate_every = 500;  ///< 0: never
  std::uint32_t validation_views = 2;
  std::uint32_t checkpoint_every = 1000;  ///< 0: only at the end of run()
};

struct TrainStats {
  std::uint64_t step = 0;                                      ///< steps taken so far
  std::uint64_t target = 0;                                    ///< the step run() is heading for
  double loss = 0;                                             ///< render loss of the last step (linear radiance)
  double visibility_loss = 0;                                  ///< visibility loss of the last step
  double val_psnr = std::numeric_limits<double>::quiet_NaN();  ///< last validation PSNR [dB] (NaN before any)
  double steps_per_second = 0;                                 ///< over this run() call
  double elapsed = 0;                                          ///< seconds of this run() call
  double eta = 0;                                              ///< seconds left in this run() call
  double learning_rate = 0;
  std::uint64_t skipped = 0;  ///< steps skipped so far because their loss was NaN/Inf
};

/// Returns false to stop training (run() then returns after saving nothing more).
using TrainCallback = std::function<bool(const TrainStats&)>;

class Trainer {
 public:
  /// Loads the training split (and validation views) of `dataset_dir` and builds the model from `config`
  /// (a run config; unknown keys and bad values are ConfigErrors).
  Trainer(const Device& device, const std::string& dataset_dir, const Json& config);

  /// Writes `dir`/config.json (the resolved config) now, and log.jsonl lines and checkpoints
  /// (`dir`/checkpoint.relit, the latest) as training goes. Creates `dir`.
  void set_output(const std::string& dir);

  /// One training step (enqueued only).
  void step();
  /// Trains until `steps()` reaches `target`, reporting every log_every steps (and at the end); validates
  /// and checkpoints on schedule and writes a final checkpoint when an output folder is set.
  TrainStats run_until(std::uint64_t target, const TrainCallback& callback = {});
  /// run_until(steps() + n).
  TrainStats run(std::uint64_t n, const TrainCallback& callback = {}) { return run_until(m_step + n, callback); }

  /// Mean PSNR [dB] of the validation views rendered with the current parameters.
  double validate();
  /// Reads the last step's losses (synchronises).
  TrainStats stats() const;

  /// Times every stage of `n` steps (waiting for the device between stages): mean milliseconds per stage.
  std::vector<std::pair<std::string, double>> profile(std::uint32_t n);

  void save_checkpoint(const std::string& path) const;
  /// Restores parameters, optimiser state, density grid and step from a checkpoint of the same config;
  /// training then continues exactly as if it had not stopped.
  void load_checkpoint(const std::string& path);

  std::uint64_t steps() const { return m_step; }
  const Json& config() const { return m_config; }
  const TrainingSettings& settings() const { return m_settings; }
  Model& model() { return *m_model; }
  const Model& model() const { return *m_model; }

 private:
  void write_log(const TrainStats& s) const;
  Device m_device;
  Json m_config;
  TrainingSettings m_settings;
  std::unique_ptr<Model> m_model;
  std::unique_ptr<nn::Loss> m_loss, m_vis_loss;
  std::unique_ptr<nn::Optimizer> m_optimizer, m_vis_optimizer;
  std::unique_ptr<render::RaySource> m_rays;
  std::unique_ptr<render::EnvironmentSamples> m_env;  // 'env+point' datasets: the training step's N_e directions
  DatasetSplit m_val;
  std::string m_out;
  std::unique_ptr<ModelPass> m_pass;
  std::vector<Buffer<float>> m_d_colors;  // dL/dcolour per colour of the model (rows)
  Buffer<float> m_ray_buf, m_targets, m_loss_value, m_aux_loss_value, m_vis_loss_value, m_guard;
  Buffer<std::uint32_t> m_pixel_ids, m_skipped;
  nn::BatchMatrix m_color_t, m_target_t, m_d_color_t;
  std::uint64_t m_step = 0;
  double m_val_psnr = std::numeric_limits<double>::quiet_NaN();
  StageTimer m_timer;
};

struct RenderSettings {
  std::uint32_t tile_rays = 1024;  ///< rays per pass (small tiles stay in cache)
  std::uint32_t seed = 0;          ///< draws the indirect directions
  /// Rays per pixel, averaged: an n x n grid in each pixel (a box filter, as the path tracer's references;
  /// anti-aliases the medium's edges). A square: 1, 4, 9, 16, ... Each sample draws its own indirect directions.
  std::uint32_t spp = 1;
  /// "" uses the model's inference_visibility setting; "network" or "march" override it.
  std::string visibility;
  /// Light the scene with this environment map as well (a model trained on 'env+point' data; it is sampled
  /// in model/environment/n_dirs directions). Null: the point light alone.
  const EnvironmentLight* environment = nullptr;
};

/// Renders `camera`'s image under `light` with the model: linear RGB (3 channels), in tiles, with progress
/// counted in rays (pixels x spp).
Image render_image(const Model& model, const Camera& camera, const PointLight& light,
                   const RenderSettings& settings = {}, const ProgressCallback& progress = {});

/// Builds the model stored in a checkpoint (its config and parameters; the dataset is not needed).
std::unique_ptr<Model> load_model(const Device& device, const std::string& checkpoint_path);

}  // namespace relit::method
