// Training of every method (Ours and the baselines): the step, its schedule (validation, logs, checkpoints),
// and resuming from a checkpoint.
#include "cl/kernel_sources.hpp"

#include <relit/cl/program.hpp>
#include <relit/io/file.hpp>
#include <relit/log.hpp>
#include <relit/method/model_io.hpp>
#include <relit/method/render_image.hpp>
#include <relit/method/trainer.hpp>
#include <relit/metrics.hpp>
#include <relit/nn/registry.hpp>
#include <relit/parallel.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace relit::method {

namespace {

TrainingSettings read_training(config::Reader& r, Json& loss, Json& vis_loss, Json& optimizer, Json& vis_optimizer) {
  TrainingSettings t;
  t.batch_rays = r.uint("batch_rays", 1200, 16, 1u << 20, "camera rays per training step");
  t.steps = r.uint("steps", 3000, 1, 1u << 30, "training steps of a run (relit train --steps overrides)");
  t.seed = r.uint("seed", 0, 0, 0xffffffffu, "seeds initialisation, ray batches and sample jitter");
  t.visibility_loss_weight = r.number("visibility_loss_weight", 1.0f, 0.0f, 1e6f, "weight of the visibility loss");
  t.log_every = r.uint("log_every", 50, 1, 1u << 30, "steps between loss readbacks (progress, log.jsonl)");
  t.validate_every = r.uint("validate_every", 500, 0, 1u << 30, "steps between validation renders (0: never)");
  t.validation_views = r.uint("validation_views", 2, 0, 1000, "validation views rendered each time");
  t.checkpoint_every = r.uint("checkpoint_every", 1000, 0, 1u << 30, "steps between checkpoints (0: only at the end)");
  const Json adam = {{"type", "Adam"}, {"learning_rate", 1e-2}, {"epsilon", 1e-15}};
  loss = r.sub("loss", Json{{"type", "L2"}}, "component", "render loss on linear radiance");
  vis_loss = r.sub("visibility_loss", Json{{"type", "L2"}}, "component",
                   "loss of the visibility net against the marched transmittance (SrgbL2 weighs the errors of "
                   "nearly shadowed samples as the metric sees them)");
  optimizer = r.sub("optimizer", adam, "component", "optimiser of θ (property net and SH head)");
  vis_optimizer = r.sub("visibility_optimizer", adam, "component", "optimiser of ψ (visibility net)");
  return t;
}

std::uint32_t step_seed(std::uint32_t seed, std::uint64_t step) {
  std::uint32_t h = seed * 0x9E3779B9u ^ static_cast<std::uint32_t>(step) * 0x85EBCA6Bu;
  h ^= h >> 16;
  return h * 0x7FEB352Du;
}

void rows_to_tiled(const Device& device, const Buffer<float>& rows, std::uint32_t n, nn::BatchMatrix& m) {
  m.resize(n);
  device.kernel("method.cl", "rows_to_tiled").args(n, m.cols(), rows, m.data()).launch(n, 64);
}

void tiled_to_rows(const Device& device, const nn::BatchMatrix& m, Buffer<float>& rows) {
  device.kernel("method.cl", "tiled_to_rows").args(m.batch(), m.cols(), m.data(), rows).launch(m.batch(), 64);
}

// The top-level keys of a run config (also read by the Trainer's constructor).
Json read_run_keys(config::Reader& r) {
  std::string listing;
  for (const auto& m : methods().entries()) listing += (listing.empty() ? "" : "; ") + m.name + " (" + m.summary + ")";
  r.choice("method", "ours", method_names(), "the method: " + listing);
  // A run's config.json names the dataset it trained on, so that a run's config trains another run as it is.
  r.string("dataset", "",
           "the dataset a run trained on: relit writes it into the run's config.json; ignored as input (the dataset "
           "argument decides)");
  return r.sub("model", Json::object(), "object", "the model (the /model objects below)");
}

// The run config's "training" object: its settings, losses and optimisers; resolved into `r`.
struct TrainingParts {
  TrainingSettings settings;
  std::unique_ptr<nn::Loss> loss, vis_loss;
  std::unique_ptr<nn::Optimizer> optimizer, vis_optimizer;
};

TrainingParts read_training_section(config::Reader& r) {
  TrainingParts t;
  config::Reader tr(r.sub("training", Json::object(), "object", "training settings"), r.pointer("training"),
                    "training");
  Json loss, vis_loss, opt, vis_opt;
  t.settings = read_training(tr, loss, vis_loss, opt, vis_opt);
  t.loss = nn::create_loss(loss, "/training/loss");
  t.vis_loss = nn::create_loss(vis_loss, "/training/visibility_loss");
  t.optimizer = nn::create_optimizer(opt, "/training/optimizer");
  t.vis_optimizer = nn::create_optimizer(vis_opt, "/training/visibility_optimizer");
  tr.set_resolved("loss", t.loss->hyperparams());
  tr.set_resolved("visibility_loss", t.vis_loss->hyperparams());
  tr.set_resolved("optimizer", t.optimizer->hyperparams());
  tr.set_resolved("visibility_optimizer", t.vis_optimizer->hyperparams());
  tr.finish();
  r.set_resolved("training", tr.resolved());
  return t;
}

}  // namespace

Json check_run_config(const Json& config) {
  if (!config.is_object()) throw ConfigError("", "the run config must be a JSON object");
  config::Reader r(config, "", "run");
  const Json model = read_run_keys(r);
  const std::string method = r.resolved().value("method", "ours");
  read_training_section(r);
  r.set_resolved("model", check_model_config(method, model, "/model"));
  r.finish();
  Json resolved = r.resolved();
  resolved.erase("dataset");
  return resolved;
}

config::Docs run_config_docs() {
  config::Docs docs;
  config::Reader r(Json::object(), "", "run");
  read_run_keys(r);
  r.sub("training", Json::object(), "object", "training settings (/training below)");
  docs.emplace_back("", r.docs());
  // Each method's "model" keys, marked with the method ("/model [bi]") for the reference.
  for (const auto& m : method_names()) {
    const std::size_t first = docs.size();
    describe_model(m, docs);
    for (std::size_t i = first; i < docs.size(); ++i) docs[i].first += " [" + m + "]";
  }
  config::Reader tr(Json::object(), "/training", "training");
  Json loss, vis_loss, opt, vis_opt;
  read_training(tr, loss, vis_loss, opt, vis_opt);
  docs.emplace_back("/training", tr.docs());
  return docs;
}

Trainer::Trainer(const Device& device, const std::string& dataset_dir, const Json& config) : m_device(device) {
  if (!config.is_object()) throw ConfigError("", "the run config must be a JSON object");
  config::Reader r(config, "", "run");
  const Json model = read_run_keys(r);
  const std::string method = r.resolved().value("method", "ours");
  TrainingParts training = read_training_section(r);
  m_settings = training.settings;
  m_loss = std::move(training.loss);
  m_vis_loss = std::move(training.vis_loss);
  m_optimizer = std::move(training.optimizer);
  m_vis_optimizer = std::move(training.vis_optimizer);
  const DatasetSplit train = load_split(dataset_dir, "train");
  // The model has an environment light exactly when the dataset has one; relit sets model/environment/enabled.
  Json model_config = model;
  {
    const bool has_env = train.environment != nullptr;
    const Json* given =
        model.contains("environment") && model["environment"].is_object() && model["environment"].contains("enabled")
            ? &model["environment"]["enabled"]
            : nullptr;
    if (given && given->is_boolean() && given->get<bool>() != has_env)
      throw ConfigError("/model/environment/enabled",
                        std::string("is ") + (has_env ? "false" : "true") + " but the dataset " + dataset_dir +
                            (has_env ? " is lit by an environment map ('env+point')" : " has no environment map") +
                            "; leave it out (relit sets it from the dataset)");
    if (!given) model_config["environment"]["enabled"] = has_env;
  }
  m_model = create_model(device, method, model_config, "/model");
  r.set_resolved("model", m_model->hyperparams());
  r.finish();
  m_config = r.resolved();
  m_config["dataset"] = fs::absolute(dataset_dir).lexically_normal().string();

  log_info("training on " + std::to_string(train.size()) + " views of " + dataset_dir + " (" +
           std::to_string(train.width) + "x" + std::to_string(train.height) + ")");
  m_rays = std::make_unique<render::RaySource>(device, train.cameras, train.lights, train.images);
  if (m_settings.validate_every && m_settings.validation_views) {
    const auto desc = read_dataset(dataset_dir);
    const std::string split = desc.splits.count("val") ? "val" : "test";
    m_val = load_split(dataset_dir, split, m_settings.validation_views);
  }
  if (train.environment) {
    m_env = std::make_unique<render::EnvironmentSamples>(device, *train.environment, m_model->env_dirs_training());
    log_info("environment light " + train.environment->file() + ": " + std::to_string(m_model->env_dirs_training()) +
             " directions per step");
  }
  m_pass = m_model->make_pass();

  // Data parallelism: this rank's rays of each global batch; every rank must train the same run on the same data.
  m_share = parallel::share();
  if (m_settings.batch_rays < m_share.stride)
    throw ConfigError("/training/batch_rays", "is " + std::to_string(m_settings.batch_rays) + ", fewer rays than the " +
                                                  std::to_string(m_share.stride) + " MPI ranks that share each batch");
  m_local_rays = m_share.count(m_settings.batch_rays);
  if (parallel::distributed()) {
    Json run = m_config;
    run.erase("dataset");  // its path may differ from machine to machine; its images are compared below
    parallel::check_same("the run config", run.dump());
    std::string data;
    data.append(reinterpret_cast<const char*>(train.images.data()), train.images.size() * sizeof(float));
    parallel::check_same("the training data (" + dataset_dir + ", a hash of its images)",
                         std::to_string(train.size()) + " views, " + std::to_string(relit::detail::fnv1a(data)));
  }

  m_model->initialize(m_settings.seed);
  m_optimizer->allocate(device, m_model->n_params());
  m_vis_optimizer->allocate(device, m_model->n_vis_params());
  const std::uint32_t b = m_local_rays;
  m_ray_buf = Buffer<float>(device, std::size_t(b) * render::kRayFloats);
  m_targets = Buffer<float>(device, 3 * std::size_t(b));
  for (std::uint32_t i = 0; i < m_model->n_colors(); ++i) m_d_colors.emplace_back(device, 3 * std::size_t(b));
  m_pixel_ids = Buffer<std::uint32_t>(device, b);
  m_loss_value = Buffer<float>(device, 1);
  m_aux_loss_value = Buffer<float>(device, 1);
  m_vis_loss_value = Buffer<float>(device, 1);
  m_guard = Buffer<float>(device, 1);
  m_skipped = Buffer<std::uint32_t>(device, 1);
  for (auto* buf : {&m_loss_value, &m_vis_loss_value, &m_guard}) buf->fill(0.0f);
  m_skipped.fill(0u);
  m_optimizer->set_guard(&m_guard);
  m_vis_optimizer->set_guard(&m_guard);
  m_color_t = nn::BatchMatrix(device, b, 3);
  m_target_t = nn::BatchMatrix(device, b, 3);
  m_d_color_t = nn::BatchMatrix(device, b, 3);
}

void Trainer::set_output(const std::string& dir) {
  if (parallel::rank() != 0) return;  // rank 0 writes the run
  io::create_directories(dir, "run folder");
  io::remove_stale_temporaries(dir);
  m_out = dir;
  io::write_file_atomic((fs::path(dir) / "config.json").string(), m_config.dump(2) + "\n");
}

void Trainer::step() {
  const auto& s = m_settings;
  const std::uint32_t b = m_local_rays;                         // this rank's rays of the global batch of s.batch_rays
  const float batch_fraction = float(b) / float(s.batch_rays);  // 1 in one process
  const std::uint32_t seed = step_seed(s.seed, m_step);
  StageTimer* timer = m_timer.enabled() ? &m_timer : nullptr;
  if (timer) timer->start();
  if (m_step % m_model->grid_refresh_every() == 0) {
    // Split over the ranks: each evaluates its part of the voxels, the others' are zero, and the sum is the grid.
    m_model->refresh_density_grid(m_share);
    if (parallel::distributed()) {
      Buffer<float>& sigma = m_model->density_grid().sigma;
      m_reduction.resize(sigma.size());
      sigma.read(m_reduction.data(), sigma.size());
      parallel::sum(m_reduction.data(), sigma.size(), "the density-grid refresh");
      sigma.write(m_reduction.data(), sigma.size());
    }
  }
  if (timer) timer->mark("density grid refresh");
  m_rays->training_batch(b, s.seed, static_cast<std::uint32_t>(m_step), m_ray_buf, m_targets, m_pixel_ids, m_share);
  if (m_env) {
    m_env->draw(s.seed, static_cast<std::uint32_t>(m_step));
    m_env->fill_background(m_ray_buf, b);
  }
  PassOptions o;
  o.training = true;
  o.seed = s.seed;
  o.iteration = static_cast<std::uint32_t>(m_step);
  o.jitter_seed = seed;
  o.env = m_env.get();
  o.timer = timer;
  o.share = m_share;
  o.batch_rays = s.batch_rays;
  m_model->render(*m_pass, m_ray_buf, b, o);
  // Render loss on the pixel colours (every colour the model renders; the last is its image).
  rows_to_tiled(m_device, m_targets, b, m_target_t);
  m_d_color_t.resize(b);
  std::vector<const Buffer<float>*> d_colors;
  const std::uint32_t n_colors = m_model->n_colors();
  for (std::uint32_t i = 0; i < n_colors; ++i) {
    rows_to_tiled(m_device, m_model->color(*m_pass, i), b, m_color_t);
    m_loss->evaluate(m_device, m_color_t, m_target_t, m_d_color_t, i + 1 == n_colors ? m_loss_value : m_aux_loss_value,
                     batch_fraction);
    tiled_to_rows(m_device, m_d_color_t, m_d_colors[i]);
    d_colors.push_back(&m_d_colors[i]);
  }
  if (timer) timer->mark("render loss");
  m_model->backward(*m_pass, m_ray_buf, d_colors, o);
  // Visibility loss against the density march (constants: θ gets nothing), backward into ψ only.
  const double visibility_fraction =
      m_model->train_visibility(*m_pass, m_ray_buf, *m_vis_loss, m_vis_loss_value, s.visibility_loss_weight, o);
  if (parallel::distributed()) {
    reduce_over_ranks(batch_fraction, visibility_fraction);
    if (timer) timer->mark("gradient reduction (MPI)");
  }
  m_device.kernel("method.cl", "step_guard").args(m_loss_value, m_vis_loss_value, m_guard, m_skipped).launch(1, 1);
  m_optimizer->step(m_model->params(), m_model->grads());
  m_vis_optimizer->step(m_model->vis_params(), m_model->vis_grads());
  if (timer) timer->mark("Adam");
  ++m_step;
}

// Each rank's gradients and losses are its share of the global batch's (the losses weighted by that share): their
// sum over the ranks, in rank order, is the single-process step's up to float rounding.
void Trainer::reduce_over_ranks(float batch_fraction, double visibility_fraction) {
  const std::size_t np = m_model->n_params(), nv = m_model->n_vis_params();
  m_reduction.resize(np + nv + 3);
  float* v = m_reduction.data();
  m_model->grads().read(v, np);
  m_model->vis_grads().read(v + np, nv);
  m_loss_value.read(v + np + nv, 1);
  m_aux_loss_value.read(v + np + nv + 1, 1);
  m_vis_loss_value.read(v + np + nv + 2, 1);
  v[np + nv] *= batch_fraction;
  v[np + nv + 1] *= batch_fraction;
  v[np + nv + 2] = float(v[np + nv + 2] * visibility_fraction);
  parallel::sum(v, m_reduction.size(), "the gradient reduction of a training step");
  m_model->grads().write(v, np);
  m_model->vis_grads().write(v + np, nv);
  m_loss_value.write(v + np + nv, 1);
  m_aux_loss_value.write(v + np + nv + 1, 1);
  m_vis_loss_value.write(v + np + nv + 2, 1);
}

TrainStats Trainer::stats() const {
  TrainStats st;
  st.step = m_step;
  st.loss = m_loss_value.read()[0];
  st.visibility_loss = m_vis_loss_value.read()[0];
  st.skipped = m_skipped.read()[0];
  st.val_psnr = m_val_psnr;
  st.learning_rate = m_optimizer->learning_rate();
  return st;
}

double Trainer::validate() {
  if (m_val.size() == 0) return m_val_psnr;
  double sum = 0;
  for (std::size_t i = 0; i < m_val.size(); ++i) {
    ImageRenderSettings rs;
    rs.seed = 7;
    rs.environment = m_val.environment.get();
    const Image img = render_image(*m_model, m_val.cameras[i], m_val.lights[i], rs);
    sum += metrics::compare(m_device, img.pixels, m_val.image(i), m_val.width, m_val.height, 3).psnr;
  }
  m_val_psnr = sum / double(m_val.size());
  return m_val_psnr;
}

void Trainer::write_log(const TrainStats& s) {
  if (m_out.empty()) return;
  Json line{{"step", s.step},        {"loss", s.loss},       {"visibility_loss", s.visibility_loss},
            {"lr", s.learning_rate}, {"skipped", s.skipped}, {"steps_per_second", s.steps_per_second},
            {"elapsed", s.elapsed}};
  if (!std::isnan(s.val_psnr)) line["val_psnr"] = s.val_psnr;
  m_pending_log += line.dump() + "\n";
}

// Appends the pending lines (their steps are now in the checkpoint); a torn last line is dropped by trim_log().
void Trainer::flush_log() {
  if (m_out.empty() || m_pending_log.empty()) return;
  io::append_file((fs::path(m_out) / "log.jsonl").string(), m_pending_log);
  m_pending_log.clear();
}

// Keeps the log lines of steps up to `last_step` that parse, rewriting log.jsonl atomically when any go.
void Trainer::trim_log(std::uint64_t last_step) const {
  const std::string path = (fs::path(m_out) / "log.jsonl").string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return;
  std::istringstream in(io::read_file(path));
  std::string line, kept;
  bool dropped = false;
  while (std::getline(in, line)) {
    const Json j = Json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (j.is_object() && j.contains("step") && j["step"].is_number_unsigned() &&
        j["step"].get<std::uint64_t>() <= last_step && !in.eof())
      kept += line + "\n";
    else
      dropped = true;
  }
  if (dropped) io::write_file_atomic(path, kept);
}

TrainStats Trainer::run_until(std::uint64_t target, const TrainCallback& callback) {
  const auto start = std::chrono::steady_clock::now();
  const std::uint64_t first = m_step;
  std::uint64_t skipped_before = stats().skipped;
  TrainStats st = stats();
  st.target = target;
  // At a step that reports: its statistics and log line (pending), then the checkpoint if one is due with the
  // lines flushed after it, and only then the callback, which may stop the run: whatever the callback sees
  // is on disk, and the log never holds a step the checkpoint lacks.
  auto measure = [&]() {
    st = stats();
    st.target = target;
    st.elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    st.steps_per_second = st.elapsed > 0 ? double(m_step - first) / st.elapsed : 0;
    st.eta = st.steps_per_second > 0 ? double(target - m_step) / st.steps_per_second : 0;
    if (st.skipped > skipped_before)
      log_warning("skipped " + std::to_string(st.skipped - skipped_before) + " step(s) before step " +
                  std::to_string(m_step) + ": the loss was not finite (NaN/Inf); parameters left unchanged");
    skipped_before = st.skipped;
    write_log(st);
  };
  std::uint64_t saved_at = std::numeric_limits<std::uint64_t>::max();
  auto checkpoint = [&]() {
    if (m_out.empty()) return;
    save_checkpoint((fs::path(m_out) / "checkpoint.relit").string());
    flush_log();
    saved_at = m_step;
  };
  while (m_step < target) {
    step();
    const bool last = m_step == target;
    bool validated = false;
    if (m_settings.validate_every && (m_step % m_settings.validate_every == 0 || last)) {
      if (parallel::rank() == 0) validate();  // the other ranks go on to the next step's reduction meanwhile
      validated = true;
    }
    const bool reports = m_step % m_settings.log_every == 0 || last || validated;
    if (reports) measure();
    if (last || (m_settings.checkpoint_every && m_step % m_settings.checkpoint_every == 0)) checkpoint();
    // Every rank runs the callback; rank 0's answer holds for all (a time budget, a stop request).
    if (reports && callback && !parallel::broadcast(callback(st), "the decision to go on training")) break;
  }
  if (m_step == first) {
    measure();
    checkpoint();
    if (callback) callback(st);
  }
  if (saved_at != m_step) checkpoint();  // stopped by the callback between checkpoints
  return st;
}

std::vector<std::pair<std::string, double>> Trainer::profile(std::uint32_t n) {
  step();  // warm-up: kernel builds and first allocations
  m_timer.enable(m_device);
  m_timer.clear();
  for (std::uint32_t i = 0; i < n; ++i) step();
  auto out = m_timer.seconds();
  m_timer = StageTimer();
  for (auto& [name, sec] : out) sec = sec * 1000.0 / n;
  return out;
}

// ---- checkpoints -------------------------------------------------------------------------------------------

void Trainer::save_checkpoint(const std::string& path) const {
  io::Checkpoint c;
  c.header["kind"] = "relit run";
  c.header["config"] = m_config;
  c.header["step"] = m_step;
  c.header["val_psnr"] = std::isnan(m_val_psnr) ? Json() : Json(m_val_psnr);
  put_model(c, *m_model);
  for (auto& [name, buf] : m_optimizer->state_buffers()) put_tensor(c, "optimizer/" + name, *buf);
  for (auto& [name, buf] : m_vis_optimizer->state_buffers()) put_tensor(c, "visibility_optimizer/" + name, *buf);
  c.tensors["skipped"] = {float(m_skipped.read()[0])};
  io::save_checkpoint(path, c);
}

void Trainer::load_checkpoint(const std::string& path) {
  const io::Checkpoint c = io::load_checkpoint(path);
  if (!c.header.contains("step") || !c.header["step"].is_number_unsigned() || !c.header.contains("config") ||
      !c.header["config"].is_object())
    throw IOError(path + ": not a relit run checkpoint (its header lacks the step and the config)");
  Json theirs = c.header["config"];
  Json ours = m_config;
  theirs.erase("dataset");
  ours.erase("dataset");
  if (theirs.contains("training")) theirs["training"].erase("steps");
  if (ours.contains("training")) ours["training"].erase("steps");
  if (theirs != ours)
    throw InvalidArgument(path +
                          ": the checkpoint was written with another config; resume with the run's own "
                          "config.json (diff: " +
                          Json::diff(ours, theirs).dump() + ")");
  get_model(c, *m_model, path);
  for (auto& [name, buf] : m_optimizer->state_buffers()) get_tensor(c, "optimizer/" + name, *buf, path);
  for (auto& [name, buf] : m_vis_optimizer->state_buffers()) get_tensor(c, "visibility_optimizer/" + name, *buf, path);
  m_step = c.header.at("step").get<std::uint64_t>();
  m_optimizer->set_step_count(m_step);
  m_vis_optimizer->set_step_count(m_step);
  const auto sk = c.tensors.find("skipped");
  m_skipped.fill(sk == c.tensors.end() ? 0u : static_cast<std::uint32_t>(sk->second.at(0)));
  const Json& v = c.header.value("val_psnr", Json());
  m_val_psnr = v.is_number() ? v.get<double>() : std::numeric_limits<double>::quiet_NaN();
  m_pending_log.clear();
  if (!m_out.empty()) trim_log(m_step);
}

}  // namespace relit::method
