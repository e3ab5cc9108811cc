// Training of every method (Ours and the baselines): steps, validation, logs, checkpoints and resuming
// (docs/design.md §4.3, §7). Presets are in presets.hpp, relighting a trained model in render_image.hpp, loading one
// from a checkpoint in model_io.hpp, the dataset reader in relit/dataset.hpp.
//
//   auto config = relit::method::preset("fast");                       // presets.hpp; or a JSON file's contents
//   relit::method::Trainer trainer(device, "data/cloud", config);
//   trainer.set_output("runs/cloud");                                  // config.json, log.jsonl, checkpoints
//   trainer.run(3000, [](const TrainStats& s) { ...; return true; });  // every log_every steps
//   relit::Image img = relit::method::render_image(trainer.model(), camera, light);
//
// A run config is {"method": one of method_names(), "model": {...}, "training": {...}}; docs/method.md describes it
// and docs/config.md lists every key. A step enqueues its work only (no host synchronisation) except at the periodic
// loss readback (log_every), validation and checkpoints.
#pragma once

#include <relit/dataset.hpp>
#include <relit/method/model.hpp>
#include <relit/render/volume_renderer.hpp>
#include <relit/render/environment.hpp>
#include <relit/nn/loss.hpp>
#include <relit/nn/optimizer.hpp>
#include <relit/progress.hpp>
#include <relit/render/rays.hpp>

#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace relit::method {

/// Every key of a run config, object by object (the "Run config" part of docs/config.md).
config::Docs run_config_docs();

/// Reads a run config as the Trainer does, without a device or a dataset: unknown keys, wrong types and bad
/// values of "method", "model" and "training" are ConfigErrors naming the JSON pointer. Returns it resolved.
Json check_run_config(const Json& config);

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

  /// Under MPI (relit/parallel.hpp) every rank trains on its share of each batch and the gradients are summed in
  /// rank order before Adam, so all ranks hold the same parameters; only rank 0 writes (set_output() is a no-op
  /// on the others) and validates, and rank 0's callback decides when to stop.
  /// Writes `dir`/config.json (the resolved config) now, and checkpoints (`dir`/checkpoint.relit, the latest)
  /// and log.jsonl lines as training goes. Log lines are appended only after the checkpoint that holds their
  /// step is written, so the log never records steps the checkpoint lacks. Creates `dir`; removes the
  /// temporaries that killed runs left in it.
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
  /// training then continues exactly as if it had not stopped. With an output folder set, lines of its
  /// log.jsonl past the checkpoint's step (or torn by a kill) are dropped.
  void load_checkpoint(const std::string& path);

  std::uint64_t steps() const { return m_step; }
  const Json& config() const { return m_config; }
  const TrainingSettings& settings() const { return m_settings; }
  Model& model() { return *m_model; }
  const Model& model() const { return *m_model; }

 private:
  void reduce_over_ranks(float batch_fraction, double visibility_fraction);
  void write_log(const TrainStats& s);
  void flush_log();
  void trim_log(std::uint64_t last_step) const;
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
  std::string m_pending_log;  // log.jsonl lines of steps not yet in a checkpoint
  std::unique_ptr<ModelPass> m_pass;
  std::vector<Buffer<float>> m_d_colors;  // dL/dcolour per colour of the model (rows)
  Buffer<float> m_ray_buf, m_targets, m_loss_value, m_aux_loss_value, m_vis_loss_value, m_guard;
  Buffer<std::uint32_t> m_pixel_ids, m_skipped;
  nn::BatchMatrix m_color_t, m_target_t, m_d_color_t;
  parallel::Share m_share;         // this rank's rays of each global batch (all of them in one process)
  std::uint32_t m_local_rays = 0;  // m_share.count(batch_rays)
  std::vector<float> m_reduction;  // host staging of the gradients summed over ranks
  std::uint64_t m_step = 0;
  double m_val_psnr = std::numeric_limits<double>::quiet_NaN();
  StageTimer m_timer;
};

}  // namespace relit::method
