// The Model base (storage, StageTimer) and the method registry: the run config's "method" key → the class.
#include <relit/error.hpp>
#include <relit/method/model.hpp>

#include "registration.hpp"

#include <algorithm>
#include <chrono>

namespace relit::method {

namespace {
double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
}  // namespace

void StageTimer::enable(const Device& device) {
  m_device = device;
  m_enabled = true;
}

void StageTimer::start() {
  if (!m_enabled) return;
  m_device.finish();
  m_last = now_seconds();
}

void StageTimer::mark(const std::string& stage) {
  if (!m_enabled) return;
  m_device.finish();
  const double t = now_seconds();
  auto it = std::find_if(m_seconds.begin(), m_seconds.end(), [&](const auto& p) { return p.first == stage; });
  if (it == m_seconds.end())
    m_seconds.emplace_back(stage, t - m_last);
  else
    it->second += t - m_last;
  m_last = t;
}

void Model::allocate_storage(std::uint32_t n_theta, std::uint32_t n_psi, std::uint32_t grid_resolution) {
  m_params = Buffer<float>(m_device, n_theta);
  m_grads = Buffer<float>(m_device, n_theta);
  m_vis_params = Buffer<float>(m_device, n_psi);
  m_vis_grads = Buffer<float>(m_device, n_psi);
  m_grads.fill(0.0f);
  m_vis_grads.fill(0.0f);
  const int g = static_cast<int>(grid_resolution);
  m_grid.dims = {g, g, g};
  m_grid.sigma = Buffer<float>(m_device, std::size_t(g) * g * g);
  m_grid.sigma.fill(0.0f);
}

void MethodRegistry::add(MethodEntry entry) {
  if (find(entry.name)) throw InvalidArgument("MethodRegistry: method '" + entry.name + "' registered twice");
  auto at = std::find_if(m_entries.begin(), m_entries.end(), [&](const MethodEntry& e) {
    return e.rank > entry.rank || (e.rank == entry.rank && e.name > entry.name);
  });
  m_entries.insert(at, std::move(entry));
}

const MethodEntry* MethodRegistry::find(const std::string& name) const {
  for (const auto& e : m_entries)
    if (e.name == name) return &e;
  return nullptr;
}

const MethodRegistry& methods() {
  static const MethodRegistry registry = [] {
    MethodRegistry r;
    detail::register_all_methods(r);
    return r;
  }();
  return registry;
}

std::vector<std::string> method_names() {
  std::vector<std::string> names;
  for (const auto& e : methods().entries()) names.push_back(e.name);
  return names;
}

std::unique_ptr<Model> create_model(const Device& device, const std::string& method, const Json& config,
                                    const std::string& pointer) {
  if (const MethodEntry* e = methods().find(method)) return e->create(device, config, pointer);
  std::string names;
  for (const auto& m : method_names()) names += (names.empty() ? "" : ", ") + m;
  throw ConfigError("/method", "unknown method '" + method + "'; valid methods: " + names);
}

void describe_model(const std::string& method, config::Docs& docs) {
  if (const MethodEntry* e = methods().find(method)) return e->describe(docs);
  throw InvalidArgument("describe_model: unknown method '" + method + "'");
}

Json check_model_config(const std::string& method, const Json& config, const std::string& pointer) {
  if (const MethodEntry* e = methods().find(method)) return e->check(config, pointer);
  throw InvalidArgument("check_model_config: unknown method '" + method + "'");
}

}  // namespace relit::method
