// Training, checkpoints and relighting of every method (Ours and the baselines).
#include <relit/cl/program.hpp>
#include <relit/dataset.hpp>
#include <relit/io/checkpoint.hpp>
#include <relit/io/file.hpp>
#include <relit/log.hpp>
#include <relit/method/trainer.hpp>
#include <relit/metrics.hpp>
#include <relit/nn/registry.hpp>
#include <relit/version.hpp>

#include "embedded_files.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;

namespace relit::method {

// ---- presets and configs -----------------------------------------------------------------------------------

std::vector<std::string> preset_names() {
  std::vector<std::string> names;
  for (const auto& f : detail::embedded_presets()) {
    std::string n = f.name;
    names.push_back(n.substr(0, n.size() - 5));  // drop ".json"
  }
  return names;
}

namespace {
Json parse_json(const std::string& text, const std::string& where) {
  try {
    return Json::parse(text);
  } catch (const Json::parse_error& e) {
    throw ConfigError("", where + ": not valid JSON: " + e.what());
  }
}

std::string join(const std::vector<std::string>& v) {
  std::string out;
  for (const auto& s : v) out += (out.empty() ? "" : ", ") + s;
  return out;
}
}  // namespace

Json preset(const std::string& name) {
  for (const auto& f : detail::embedded_presets())
    if (name + ".json" == f.name) return parse_json(f.text, "preset '" + name + "'");
  throw InvalidArgument("unknown preset '" + name + "'; presets: " + join(preset_names()) + " (or give a .json file)");
}

Json load_run_config(const std::string& spec) {
  const auto names = preset_names();
  if (std::find(names.begin(), names.end(), spec) != names.end()) return preset(spec);
  if (!fs::exists(spec))
    throw IOError("config '" + spec + "' is neither a preset (" + join(names) + ") nor an existing file");
  return parse_json(io::read_file(spec), spec);
}

std::string config_for_method(const std::string& spec, const std::string& method) {
  if (method.empty()) return spec;
  const auto methods = method_names();
  if (std::find(methods.begin(), methods.end(), method) == methods.end())
    throw InvalidArgument("unknown method '" + method + "'; methods: " + join(methods));
  if (method == "ours" || (spec != "fast" && spec != "paper")) return spec;
  return method + "-" + spec;
}

void set_method(Json& config, const std::string& method, const std::string& source) {
  if (method.empty()) return;
  config_for_method("fast", method);  // an unknown method is an error naming the valid ones
  if (config.contains("method") && config["method"] != method)
    throw ConfigError("/method",
                      "is " + config["method"].dump() + " in " + source + " but the method asked for is " + method);
  config["method"] = method;
}

// ---- datasets ----------------------------------------------------------------------------------------------

std::vector<float> DatasetSplit::image(std::size_t i) const {
  const std::size_t n = std::size_t(width) * height * 3;
  return std::vector<float>(images.begin() + i * n, images.begin() + (i + 1) * n);
}

namespace {
// The "environment" entry of a transforms file: null, or {file, scale, visible} (docs/dataset-format.md).
std::shared_ptr<const EnvironmentLight> load_environment(const std::string& dataset_dir, const std::string& file,
                                                         const Json& env) {
  if (env.is_null()) return nullptr;
  const std::string where = (fs::path(dataset_dir) / file).string() + ": environment";
  if (!env.is_object() || !env.contains("file") || !env["file"].is_string())
    throw IOError(where + " must be null or {\"file\": ..., \"scale\": ..., \"visible\": ...}, got " + env.dump());
  const Json scale = env.value("scale", Json(1.0));
  const Json visible = env.value("visible", Json(false));
  if (!scale.is_number() || !std::isfinite(scale.get<double>()) || scale.get<double>() < 0)
    throw IOError(where + "/scale must be a finite number >= 0, got " + scale.dump());
  if (!visible.is_boolean()) throw IOError(where + "/visible must be true or false, got " + visible.dump());
  const std::string path = (fs::path(dataset_dir) / env["file"].get<std::string>()).string();
  return std::make_shared<const EnvironmentLight>(read_image(path), scale.get<float>(), visible.get<bool>(), path);
}
}  // namespace

DatasetSplit load_split(const std::string& dataset_dir, const std::string& split, std::size_t max_views) {
  const DatasetDescription desc = read_dataset(dataset_dir);
  auto it = desc.splits.find(split);
  if (it == desc.splits.end() || it->second.empty()) {
    std::vector<std::string> have;
    for (const auto& [k, v] : desc.splits) have.push_back(k);
    throw IOError("dataset " + dataset_dir + " has no '" + split + "' views (splits: " + join(have) + ")");
  }
  const auto& frames = it->second;
  std::vector<std::size_t> picks;
  const std::size_t n = max_views && max_views < frames.size() ? max_views : frames.size();
  for (std::size_t k = 0; k < n; ++k) picks.push_back(k * frames.size() / n);
  DatasetSplit out;
  out.split = split;
  for (std::size_t k : picks) {
    const auto& f = frames[k];
    const std::string path = (fs::path(dataset_dir) / f.file_path).string();
    const Image img = read_image(path);
    if (img.channels < 3)
      throw IOError(path + ": expected an RGB(A) image, it has " + std::to_string(img.channels) + " channels");
    if (img.width != f.camera.width || img.height != f.camera.height)
      throw IOError(path + ": the image is " + std::to_string(img.width) + "x" + std::to_string(img.height) +
                    " but its camera says " + std::to_string(f.camera.width) + "x" + std::to_string(f.camera.height));
    if (out.cameras.empty()) {
      out.width = img.width;
      out.height = img.height;
    } else if (img.width != out.width || img.height != out.height) {
      throw IOError(path + ": all images of a split must have the same size");
    }
    for (std::size_t p = 0; p < std::size_t(img.width) * img.height; ++p)
      for (int c = 0; c < 3; ++c) {
        const float v = img.pixels[p * img.channels + c];
        if (!std::isfinite(v)) throw IOError(path + ": pixel " + std::to_string(p) + " is not finite");
        out.images.push_back(v);
      }
    out.names.push_back(fs::path(f.file_path).stem().string());
    out.cameras.push_back(f.camera);
    out.lights.push_back(f.light);
  }
  out.environment = load_environment(dataset_dir, "transforms_" + split + ".json", desc.environment);
  return out;
}

std::shared_ptr<const EnvironmentLight> dataset_environment(const std::string& dataset_dir) {
  return load_environment(dataset_dir, "transforms_*.json", read_dataset(dataset_dir).environment);
}

// ---- trainer -----------------------------------------------------------------------------------------------

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
  r.choice("method", "ours", method_names(),
           "the method: ours (DESIGN §4.3), ours_brdf (Ours + BRDF for solids, §4.4), bi (Bi et al.'s Neural "
           "Reflectance Field) or nerv (NeRV), §4.5");
  return r.sub("model", Json::object(), "object", "the model (the /model objects below)");
}

}  // namespace

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
  Json loss, vis_loss, opt, vis_opt;
  {
    config::Reader tr(r.sub("training", Json::object(), "object", "training settings"), r.pointer("training"),
                      "training");
    m_settings = read_training(tr, loss, vis_loss, opt, vis_opt);
    m_loss = nn::create_loss(loss, "/training/loss");
    m_vis_loss = nn::create_loss(vis_loss, "/training/visibility_loss");
    m_optimizer = nn::create_optimizer(opt, "/training/optimizer");
    m_vis_optimizer = nn::create_optimizer(vis_opt, "/training/visibility_optimizer");
    tr.set_resolved("loss", m_loss->hyperparams());
    tr.set_resolved("visibility_loss", m_vis_loss->hyperparams());
    tr.set_resolved("optimizer", m_optimizer->hyperparams());
    tr.set_resolved("visibility_optimizer", m_vis_optimizer->hyperparams());
    tr.finish();
    r.set_resolved("training", tr.resolved());
  }
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

  m_model->initialize(m_settings.seed);
  m_optimizer->allocate(device, m_model->n_params());
  m_vis_optimizer->allocate(device, m_model->n_vis_params());
  const std::uint32_t b = m_settings.batch_rays;
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
  fs::create_directories(dir);
  m_out = dir;
  io::write_file_atomic((fs::path(dir) / "config.json").string(), m_config.dump(2) + "\n");
}

void Trainer::step() {
  const auto& s = m_settings;
  const std::uint32_t b = s.batch_rays;
  const std::uint32_t seed = step_seed(s.seed, m_step);
  StageTimer* timer = m_timer.enabled() ? &m_timer : nullptr;
  if (timer) timer->start();
  if (m_step % m_model->grid_refresh_every() == 0) m_model->refresh_density_grid();
  if (timer) timer->mark("density grid refresh");
  m_rays->training_batch(b, s.seed, static_cast<std::uint32_t>(m_step), m_ray_buf, m_targets, m_pixel_ids);
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
  m_model->render(*m_pass, m_ray_buf, b, o);
  // Render loss on the pixel colours (every colour the model renders; the last is its image).
  rows_to_tiled(m_device, m_targets, b, m_target_t);
  m_d_color_t.resize(b);
  std::vector<const Buffer<float>*> d_colors;
  const std::uint32_t n_colors = m_model->n_colors();
  for (std::uint32_t i = 0; i < n_colors; ++i) {
    rows_to_tiled(m_device, m_model->color(*m_pass, i), b, m_color_t);
    m_loss->evaluate(m_device, m_color_t, m_target_t, m_d_color_t, i + 1 == n_colors ? m_loss_value : m_aux_loss_value);
    tiled_to_rows(m_device, m_d_color_t, m_d_colors[i]);
    d_colors.push_back(&m_d_colors[i]);
  }
  if (timer) timer->mark("render loss");
  m_model->backward(*m_pass, m_ray_buf, d_colors, o);
  // Visibility loss against the density march (constants: θ gets nothing), backward into ψ only.
  m_model->train_visibility(*m_pass, m_ray_buf, *m_vis_loss, m_vis_loss_value, s.visibility_loss_weight, o);
  m_device.kernel("method.cl", "step_guard").args(m_loss_value, m_vis_loss_value, m_guard, m_skipped).launch(1, 1);
  m_optimizer->step(m_model->params(), m_model->grads());
  m_vis_optimizer->step(m_model->vis_params(), m_model->vis_grads());
  if (timer) timer->mark("Adam");
  ++m_step;
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
    RenderSettings rs;
    rs.seed = 7;
    rs.environment = m_val.environment.get();
    const Image img = render_image(*m_model, m_val.cameras[i], m_val.lights[i], rs);
    sum += metrics::compare(m_device, img.pixels, m_val.image(i), m_val.width, m_val.height, 3).psnr;
  }
  m_val_psnr = sum / double(m_val.size());
  return m_val_psnr;
}

void Trainer::write_log(const TrainStats& s) const {
  if (m_out.empty()) return;
  Json line{{"step", s.step},        {"loss", s.loss},       {"visibility_loss", s.visibility_loss},
            {"lr", s.learning_rate}, {"skipped", s.skipped}, {"steps_per_second", s.steps_per_second},
            {"elapsed", s.elapsed}};
  if (!std::isnan(s.val_psnr)) line["val_psnr"] = s.val_psnr;
  std::ofstream out(fs::path(m_out) / "log.jsonl", std::ios::app);
  out << line.dump() << "\n";
  if (!out) throw IOError("cannot append to " + (fs::path(m_out) / "log.jsonl").string());
}

TrainStats Trainer::run_until(std::uint64_t target, const TrainCallback& callback) {
  const auto start = std::chrono::steady_clock::now();
  const std::uint64_t first = m_step;
  std::uint64_t skipped_before = stats().skipped;
  TrainStats st = stats();
  st.target = target;
  auto report = [&]() {
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
    return !callback || callback(st);
  };
  while (m_step < target) {
    step();
    const bool last = m_step == target;
    bool validated = false;
    if (m_settings.validate_every && (m_step % m_settings.validate_every == 0 || last)) {
      validate();
      validated = true;
    }
    if (!m_out.empty() && m_settings.checkpoint_every && m_step % m_settings.checkpoint_every == 0 && !last)
      save_checkpoint((fs::path(m_out) / "checkpoint.relit").string());
    if (m_step % m_settings.log_every == 0 || last || validated) {
      if (!report()) break;
    }
  }
  if (!m_out.empty()) save_checkpoint((fs::path(m_out) / "checkpoint.relit").string());
  if (m_step == first) report();
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

namespace {
void put(io::Checkpoint& c, const std::string& name, const Buffer<float>& b) { c.tensors[name] = b.read(); }
void get(const io::Checkpoint& c, const std::string& name, Buffer<float>& b, const std::string& path) {
  auto it = c.tensors.find(name);
  if (it == c.tensors.end()) throw IOError(path + ": checkpoint has no tensor '" + name + "'");
  if (it->second.size() != b.size())
    throw IOError(path + ": tensor '" + name + "' has " + std::to_string(it->second.size()) +
                  " values, the model needs " + std::to_string(b.size()) + " (a checkpoint of another config?)");
  b.write(it->second);
}
}  // namespace

void Trainer::save_checkpoint(const std::string& path) const {
  io::Checkpoint c;
  c.header["kind"] = "relit run";
  c.header["config"] = m_config;
  c.header["step"] = m_step;
  c.header["val_psnr"] = std::isnan(m_val_psnr) ? Json() : Json(m_val_psnr);
  put(c, "theta", m_model->params());
  put(c, "psi", m_model->vis_params());
  put(c, "density_grid", m_model->density_grid().sigma);
  for (auto& [name, buf] : m_optimizer->state_buffers()) put(c, "optimizer/" + name, *buf);
  for (auto& [name, buf] : m_vis_optimizer->state_buffers()) put(c, "visibility_optimizer/" + name, *buf);
  c.tensors["skipped"] = {float(m_skipped.read()[0])};
  io::save_checkpoint(path, c);
}

void Trainer::load_checkpoint(const std::string& path) {
  const io::Checkpoint c = io::load_checkpoint(path);
  Json theirs = c.header.value("config", Json());
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
  get(c, "theta", m_model->params(), path);
  get(c, "psi", m_model->vis_params(), path);
  get(c, "density_grid", m_model->density_grid().sigma, path);
  for (auto& [name, buf] : m_optimizer->state_buffers()) get(c, "optimizer/" + name, *buf, path);
  for (auto& [name, buf] : m_vis_optimizer->state_buffers()) get(c, "visibility_optimizer/" + name, *buf, path);
  m_step = c.header.at("step").get<std::uint64_t>();
  m_optimizer->set_step_count(m_step);
  m_vis_optimizer->set_step_count(m_step);
  const auto sk = c.tensors.find("skipped");
  m_skipped.fill(sk == c.tensors.end() ? 0u : static_cast<std::uint32_t>(sk->second.at(0)));
  const Json& v = c.header.value("val_psnr", Json());
  m_val_psnr = v.is_number() ? v.get<double>() : std::numeric_limits<double>::quiet_NaN();
}

std::unique_ptr<Model> load_model(const Device& device, const std::string& path) {
  const io::Checkpoint c = io::load_checkpoint(path);
  if (!c.header.contains("config") || !c.header["config"].contains("model"))
    throw IOError(path + ": not a relit run checkpoint (no model config in its header)");
  const std::string method = c.header["config"].value("method", "ours");
  auto model = create_model(device, method, c.header["config"]["model"], "/model");
  get(c, "theta", model->params(), path);
  get(c, "psi", model->vis_params(), path);
  get(c, "density_grid", model->density_grid().sigma, path);
  return model;
}

// ---- relighting --------------------------------------------------------------------------------------------

Image render_image(const Model& model, const Camera& camera, const PointLight& light, const RenderSettings& settings,
                   const ProgressCallback& progress) {
  camera.validate();
  light.validate();
  if (settings.tile_rays == 0) throw InvalidArgument("render_image: tile_rays must be positive");
  const std::uint32_t spp = settings.spp;
  std::vector<std::array<float, 2>> offsets{render::pixel_sample_offset(spp, 0)};  // throws unless spp is a square
  for (std::uint32_t s = 1; s < spp; ++s) offsets.push_back(render::pixel_sample_offset(spp, s));
  const std::string vis = settings.visibility.empty() ? model.inference_visibility() : settings.visibility;
  if (vis != "network" && vis != "march")
    throw InvalidArgument("render_image: visibility must be \"network\" or \"march\", got \"" + vis + "\"");
  const Device& device = model.device();
  const std::uint32_t total = static_cast<std::uint32_t>(camera.width) * camera.height;
  std::uint32_t tile = std::min(settings.tile_rays, total);
  std::unique_ptr<render::EnvironmentSamples> env;
  if (settings.environment) {
    if (!model.has_environment())
      throw InvalidArgument(
          "render_image: the model was trained without an environment light; render it under "
          "its point light alone (no environment)");
    env = std::make_unique<render::EnvironmentSamples>(device, *settings.environment, model.env_dirs());
  }
  // Keep a tile's network queries near 2^19 (N_e visibility queries per sample with an environment, ...).
  tile = std::min(tile, std::max<std::uint32_t>(16, (1u << 19) / model.queries_per_ray()));
  const auto pass = model.make_pass();
  Buffer<float> rays(device, std::size_t(tile) * render::kRayFloats);
  Image out(camera.width, camera.height, 3);
  std::vector<float> sample(std::size_t(tile) * 3);
  const render::ImageRays image_rays(device, camera, light);
  ProgressTracker tracker(progress, std::uint64_t(total) * spp, "rays");
  for (std::uint32_t first = 0, k = 0; first < total; first += tile, ++k) {
    const std::uint32_t n = std::min(tile, total - first);
    float* dst = out.pixels.data() + std::size_t(first) * 3;
    for (std::uint32_t s = 0; s < spp; ++s) {
      const std::uint32_t iteration = k * spp + s;  // spp 1: the tile's index
      image_rays(first, n, rays, offsets[s]);
      if (env) {
        env->draw(settings.seed, iteration);
        env->fill_background(rays, n);
      }
      PassOptions o;
      o.seed = settings.seed;
      o.iteration = iteration;
      o.jitter_seed = settings.seed;
      o.march_visibility = vis == "march";
      o.env = env.get();
      model.render(*pass, rays, n, o);
      model.color(*pass, model.n_colors() - 1).read(sample.data(), 3 * std::size_t(n));
      for (std::size_t i = 0; i < 3 * std::size_t(n); ++i) dst[i] += sample[i];  // out starts at 0
      tracker.update(std::uint64_t(first) * spp + std::uint64_t(n) * (s + 1));
    }
    for (std::size_t i = 0; i < 3 * std::size_t(n); ++i) dst[i] /= static_cast<float>(spp);
  }
  return out;
}

}  // namespace relit::method
