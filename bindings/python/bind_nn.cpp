// Python binding of the nn family: encodings, networks, losses and optimisers callable on numpy arrays,
// so users can check them against their own code.
//
// Each Python object owns its component, a device, and device buffers for its parameters and gradients.
// Arrays are row-major float32 (samples x features); conversion to relit's tiled layout happens here.
#include "bindings.hpp"
#include "convert.hpp"

#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <relit/config_reference.hpp>
#include <relit/nn/registry.hpp>

#include <random>

namespace py = pybind11;

namespace relit::python {

namespace {

Json config_json(const py::object& config) {
  if (py::isinstance<py::str>(config)) return parse_json(config.cast<std::string>(), "the config string");
  return json_from_python(config);
}

// A 2-D array with `cols` columns → BatchMatrix.
std::uint32_t rows_of(const FloatArray& a, std::uint32_t cols, const char* what) {
  if (a.ndim() != 2 || static_cast<std::uint32_t>(a.shape(1)) != cols)
    throw InvalidArgument(
        std::string(what) + " must have shape (n, " + std::to_string(cols) + "), got " +
        std::string(py::str(py::tuple(py::cast(std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()))))));
  return static_cast<std::uint32_t>(a.shape(0));
}

void upload(nn::BatchMatrix& m, const FloatArray& a) {
  m.upload_row_major(std::vector<float>(a.data(), a.data() + a.size()));
}

FloatArray download(const nn::BatchMatrix& m) {
  const auto host = m.download_row_major();
  FloatArray out({static_cast<py::ssize_t>(m.batch()), static_cast<py::ssize_t>(m.cols())});
  std::copy(host.begin(), host.end(), out.mutable_data());
  return out;
}

FloatArray to_array(const std::vector<float>& v) {
  return FloatArray(std::vector<py::ssize_t>{static_cast<py::ssize_t>(v.size())}, v.data());  // copies
}

// Parameters and gradients of one component on one device.
template <class Component>
struct Owned {
  Device device;
  std::unique_ptr<Component> component;
  Buffer<float> params, grads;

  void init(std::uint64_t seed) {
    const std::uint32_t n = component->n_params();
    std::vector<float> host(n);
    if (n) component->initialize_params(host.data(), seed);
    params = Buffer<float>(device, host);
    grads = Buffer<float>(device, n);
    grads.fill(0.0f);
  }
  nn::ConstParamSlice cparams() const { return {&params, 0}; }
  nn::ParamSlice gslice() { return {&grads, 0}; }
  std::unique_ptr<nn::Workspace> workspace;

  virtual ~Owned() = default;
  virtual void run_inference(const nn::BatchMatrix& in, nn::BatchMatrix& out) = 0;
  virtual void run_training(const nn::BatchMatrix& in, nn::BatchMatrix& out, const nn::BatchMatrix& d_out,
                            nn::BatchMatrix& d_in) = 0;

  FloatArray forward(const FloatArray& x) {
    const std::uint32_t n = rows_of(x, component->n_input_dims(), "input");
    nn::BatchMatrix in(device, n, component->n_input_dims()), out(device, n, component->n_output_dims());
    upload(in, x);
    run_inference(in, out);
    return download(out);
  }
  /// (dL/dx, dL/dparams) for the given dL/d(output), after a training forward pass on x.
  py::tuple backward(const FloatArray& x, const FloatArray& d_out) {
    const std::uint32_t n = rows_of(x, component->n_input_dims(), "input");
    if (rows_of(d_out, component->n_output_dims(), "d_output") != n)
      throw InvalidArgument("input and d_output have different numbers of rows");
    nn::BatchMatrix in(device, n, component->n_input_dims()), out(device, n, component->n_output_dims()),
        dout(device, n, component->n_output_dims()), din(device, n, component->n_input_dims());
    upload(in, x);
    upload(dout, d_out);
    run_training(in, out, dout, din);
    return py::make_tuple(download(din), to_array(grads.read()));
  }
  FloatArray get_params() const { return to_array(params.read()); }
  void set_params(const FloatArray& p) {
    if (static_cast<std::size_t>(p.size()) != params.size())
      throw InvalidArgument("expected " + std::to_string(params.size()) + " parameters, got " +
                            std::to_string(p.size()));
    params.write(std::vector<float>(p.data(), p.data() + p.size()));
  }
};

struct PyEncoding : Owned<nn::Encoding> {
  PyEncoding(const py::object& config, std::uint32_t n_input_dims, const py::object& dev, std::uint64_t seed) {
    device = device_arg(dev);
    component = nn::create_encoding(config_json(config), n_input_dims);
    workspace = component->make_workspace(device);
    init(seed);
  }
  void run_inference(const nn::BatchMatrix& in, nn::BatchMatrix& out) override {
    component->forward(device, cparams(), in, out, 0, workspace.get());
  }
  void run_training(const nn::BatchMatrix& in, nn::BatchMatrix& out, const nn::BatchMatrix& d_out,
                    nn::BatchMatrix& d_in) override {
    component->forward(device, cparams(), in, out, 0, workspace.get());
    component->backward(device, cparams(), in, d_out, 0, gslice(), false, &d_in, workspace.get());
  }
};

struct PyNetwork : Owned<nn::Network> {
  PyNetwork(const py::object& config, std::uint32_t n_in, std::uint32_t n_out, const py::object& dev,
            std::uint64_t seed) {
    device = device_arg(dev);
    component = nn::create_network(config_json(config), n_in, n_out);
    workspace = component->make_workspace(device);
    init(seed);
  }
  void run_inference(const nn::BatchMatrix& in, nn::BatchMatrix& out) override {
    component->inference(device, cparams(), in, out);
  }
  void run_training(const nn::BatchMatrix& in, nn::BatchMatrix& out, const nn::BatchMatrix& d_out,
                    nn::BatchMatrix& d_in) override {
    component->forward(device, cparams(), in, out, *workspace);
    component->backward(device, cparams(), in, out, d_out, gslice(), false, &d_in, *workspace);
  }
};

struct PyLoss {
  Device device;
  std::unique_ptr<nn::Loss> loss;
  PyLoss(const py::object& config, const py::object& dev)
      : device(device_arg(dev)), loss(nn::create_loss(config_json(config))) {}
  py::tuple evaluate(const FloatArray& prediction, const FloatArray& target, float scale) {
    const auto cols = prediction.ndim() == 2 ? static_cast<std::uint32_t>(prediction.shape(1)) : 0u;
    const std::uint32_t n = rows_of(prediction, cols, "prediction");
    if (rows_of(target, cols, "target") != n) throw InvalidArgument("prediction and target have different shapes");
    nn::BatchMatrix p(device, n, cols), t(device, n, cols), g(device, n, cols);
    upload(p, prediction);
    upload(t, target);
    Buffer<float> value(device, 1);
    loss->evaluate(device, p, t, g, value, scale);
    return py::make_tuple(value.read()[0], download(g));
  }
};

struct PyOptimizer {
  Device device;
  std::unique_ptr<nn::Optimizer> optimizer;
  Buffer<float> params, grads;
  PyOptimizer(const py::object& config, const py::object& dev)
      : device(device_arg(dev)), optimizer(nn::create_optimizer(config_json(config))) {}
  FloatArray step(const FloatArray& p, const FloatArray& g) {
    if (p.size() != g.size()) throw InvalidArgument("params and grads differ in size");
    const auto n = static_cast<std::size_t>(p.size());
    if (params.size() != n) {
      if (optimizer->step_count() != 0)
        throw InvalidArgument("this optimizer was stepping " + std::to_string(params.size()) + " parameters, got " +
                              std::to_string(n));
      optimizer->allocate(device, n);
      params = Buffer<float>(device, n);
      grads = Buffer<float>(device, n);
    }
    params.write(p.data(), n);
    grads.write(g.data(), n);
    optimizer->step(params, grads);
    FloatArray out(p.request().shape);
    params.read(out.mutable_data(), n);
    return out;
  }
};

template <class T>
void bind_owned_common(py::class_<T>& cls) {
  cls.def_property("params", &T::get_params, &T::set_params, "flat float32 parameter vector (get/set)")
      .def_property_readonly("n_params", [](const T& t) { return t.component->n_params(); })
      .def_property_readonly("n_input_dims", [](const T& t) { return t.component->n_input_dims(); })
      .def_property_readonly("n_output_dims", [](const T& t) { return t.component->n_output_dims(); })
      .def_property_readonly("type", [](const T& t) { return t.component->type(); })
      .def_property_readonly(
          "hyperparams", [](const T& t) { return json_to_python(t.component->hyperparams()); },
          "resolved hyperparameters (dict with 'type')")
      .def_property_readonly("device", [](const T& t) { return t.device; });
}

}  // namespace

void bind_nn(py::module_& root) {
  py::module_ m = root.def_submodule("nn", "Encodings, networks, losses and optimisers on numpy arrays.");

  py::class_<PyEncoding> enc(m, "Encoding",
                             "Encoding(config, n_input_dims, device=None, seed=0): a relit encoding with its own "
                             "parameters. config is a dict or JSON text with \"type\".");
  enc.def(py::init<const py::object&, std::uint32_t, const py::object&, std::uint64_t>(), py::arg("config"),
          py::arg("n_input_dims"), py::arg("device") = py::none(), py::arg("seed") = 0)
      .def("forward", &PyEncoding::forward, py::arg("x"), "x: (n, n_input_dims) → (n, n_output_dims)")
      .def("backward", &PyEncoding::backward, py::arg("x"), py::arg("d_output"),
           "Returns (dL/dx, dL/dparams) for the given dL/d(output).");
  bind_owned_common(enc);

  py::class_<PyNetwork> net(m, "Network",
                            "Network(config, n_input_dims, n_output_dims, device=None, seed=0): e.g. "
                            "{\"type\": \"FullyFusedMLP\", \"n_neurons\": 64, \"n_hidden_layers\": 2}.");
  net.def(py::init<const py::object&, std::uint32_t, std::uint32_t, const py::object&, std::uint64_t>(),
          py::arg("config"), py::arg("n_input_dims"), py::arg("n_output_dims"), py::arg("device") = py::none(),
          py::arg("seed") = 0)
      .def("forward", &PyNetwork::forward, py::arg("x"), "inference: x (n, n_input_dims) → (n, n_output_dims)")
      .def("backward", &PyNetwork::backward, py::arg("x"), py::arg("d_output"),
           "Returns (dL/dx, dL/dparams) for the given dL/d(output).");
  bind_owned_common(net);

  py::class_<PyLoss>(m, "Loss",
                     "Loss(config, device=None): {\"type\": \"L2\" | \"RelativeL2\" | \"ToneMappedL2\" | \"SrgbL2\"}.")
      .def(py::init<const py::object&, const py::object&>(), py::arg("config"), py::arg("device") = py::none())
      .def("evaluate", &PyLoss::evaluate, py::arg("prediction"), py::arg("target"), py::arg("scale") = 1.0f,
           "Returns (mean loss, dL/dprediction times scale).")
      .def_property_readonly("hyperparams", [](const PyLoss& l) { return json_to_python(l.loss->hyperparams()); });

  py::class_<PyOptimizer>(m, "Optimizer",
                          "Optimizer(config, device=None): {\"type\": \"Adam\", \"learning_rate\": ...}.")
      .def(py::init<const py::object&, const py::object&>(), py::arg("config"), py::arg("device") = py::none())
      .def("step", &PyOptimizer::step, py::arg("params"), py::arg("grads"), "One update; returns the new parameters.")
      .def_property_readonly("step_count", [](const PyOptimizer& o) { return o.optimizer->step_count(); })
      .def_property_readonly("learning_rate", [](const PyOptimizer& o) { return o.optimizer->learning_rate(); })
      .def_property_readonly("hyperparams",
                             [](const PyOptimizer& o) { return json_to_python(o.optimizer->hyperparams()); });

  m.def("config_reference", &config_reference_markdown, "The configuration reference (docs/config.md) as Markdown.");
}

}  // namespace relit::python
