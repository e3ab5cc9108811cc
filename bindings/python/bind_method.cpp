// Python binding of the method: training and relighting.
//   trainer = relit.Trainer("data/cloud", config="fast", out="runs/cloud")
//   for stats in trainer.run(3000):               # a TrainStats every training.log_every steps
//       print(stats.step, stats.loss, stats.val_psnr)
//   img = trainer.model.render(camera, relit.PointLight((0, -3, 3), 800))   # (H, W, 3) float32, linear
//   model = relit.Model.load("runs/cloud/checkpoint.relit")
//   relit.export_vdb(model, "cloud.vdb", resolution=128)   # density, albedo, g for Blender, Houdini, relit
//   relit.render_orbit(model, "out/cloud", 48, orbit="light")  # out/cloud_0000.png ... and out/cloud.mp4
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "bindings.hpp"
#include "convert.hpp"

#include <relit/method/export.hpp>
#include <relit/method/model_io.hpp>
#include <relit/method/presets.hpp>
#include <relit/method/render_image.hpp>
#include <relit/method/render_video.hpp>
#include <relit/method/trainer.hpp>

#include <algorithm>

namespace py = pybind11;

namespace relit::python {

namespace {

// A run config from a preset name, a .json path or a dict; `method` (when not None) picks that method's preset
// for "fast"/"paper" and must agree with the config's "method".
Json config_from(const py::object& config, const py::object& method_arg) {
  const std::string m = method_arg.is_none() ? std::string() : method_arg.cast<std::string>();
  Json c;
  if (py::isinstance<py::str>(config))
    c = method::load_run_config(method::config_for_method(config.cast<std::string>(), m));
  else if (py::isinstance<py::dict>(config))
    c = json_from_python(config);
  else
    throw InvalidArgument("config must be a preset name, a .json path or a dict");
  method::set_method(c, m, py::isinstance<py::str>(config) ? config.cast<std::string>() : "the config dict");
  return c;
}

// `for stats in trainer.run(n)`: trains in chunks of training.log_every steps, yielding after each.
struct RunIterator {
  method::Trainer* trainer;
  std::uint64_t target;
  std::uint64_t every;
  method::TrainStats next() {
    if (trainer->steps() >= target) throw py::stop_iteration();
    const std::uint64_t to = std::min(target, trainer->steps() + every);
    py::gil_scoped_release release;
    auto s = trainer->run_until(to);
    s.target = target;
    return s;
  }
};

PointLight light_from(const py::object& light) {
  if (py::isinstance<PointLight>(light)) return light.cast<PointLight>();
  throw InvalidArgument("light must be a relit.PointLight");
}

py::array_t<float> render(const method::Model& model, const Camera& camera, const py::object& light,
                          const std::string& visibility, std::uint32_t seed, const py::object& environment,
                          std::uint32_t spp) {
  const PointLight l = light_from(light);
  method::ImageRenderSettings rs;
  rs.visibility = visibility;
  rs.seed = seed;
  rs.spp = spp;
  if (!environment.is_none()) {
    if (!py::isinstance<EnvironmentLight>(environment))
      throw InvalidArgument("environment must be a relit.EnvironmentLight or None");
    rs.environment = environment.cast<const EnvironmentLight*>();
  }
  Image img;
  {
    py::gil_scoped_release release;
    img = method::render_image(model, camera, l, rs);
  }
  return image_to_numpy(img);
}

// A 1-D float32 array of `v`.
py::array_t<float> vector_array(const std::vector<float>& v) {
  py::array_t<float> a(std::vector<py::ssize_t>{py::ssize_t(v.size())});
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

// A (res, res, res[, 3]) array indexed [z, y, x] of the values `v` (x fastest).
py::array_t<float> volume(const std::vector<float>& v, int res, int channels) {
  std::vector<py::ssize_t> shape{res, res, res};
  if (channels > 1) shape.push_back(channels);
  py::array_t<float> a(shape);
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

Float3 triple_from(const py::object& v, const char* what) {
  if (py::isinstance<py::float_>(v) || py::isinstance<py::int_>(v)) {
    const float x = v.cast<float>();
    return {x, x, x};
  }
  const auto t = v.cast<std::vector<float>>();
  if (t.size() != 3) throw InvalidArgument(std::string(what) + " takes 3 values (or one for the intensity)");
  return {t[0], t[1], t[2]};
}

std::vector<std::string> video(const method::Model& model, const std::string& prefix,
                               const std::vector<method::Keyframe>& frames, int width, const py::object& height,
                               float fov, std::uint32_t spp, int fps, bool mp4, const std::string& visibility) {
  method::VideoSettings vs;
  vs.width = width;
  vs.height = height.is_none() ? width : height.cast<int>();
  vs.fov = fov;
  vs.render.spp = spp;
  vs.render.visibility = visibility;
  vs.fps = fps;
  vs.mp4 = mp4;
  py::gil_scoped_release release;
  return method::render_video(model, frames, prefix, vs);
}

}  // namespace

void bind_method(py::module_& m) {
  py::class_<EnvironmentLight, std::shared_ptr<EnvironmentLight>>(
      m, "EnvironmentLight", "A lat-long HDR environment map (z up) lighting the scene from infinity.")
      .def(py::init([](const std::string& file, float scale, bool visible) {
             return std::make_shared<EnvironmentLight>(read_image(file), scale, visible, file);
           }),
           py::arg("file"), py::arg("scale") = 1.0f, py::arg("visible") = false,
           "Loads a lat-long map (.exr/.hdr); radiance = scale x texel; visible: camera rays that miss see it.")
      .def_static(
          "from_dataset",
          [](const std::string& dataset) {
            auto env = dataset_environment(dataset);
            if (!env) throw InvalidArgument("dataset " + dataset + " has no environment light ('point' lighting)");
            return std::make_shared<EnvironmentLight>(*env);
          },
          py::arg("dataset"), "The environment light of an 'env+point' dataset folder.")
      .def_property_readonly("scale", &EnvironmentLight::scale)
      .def_property_readonly("visible", &EnvironmentLight::visible)
      .def_property_readonly("file", &EnvironmentLight::file)
      .def("__repr__", [](const EnvironmentLight& e) {
        return "EnvironmentLight(file='" + e.file() + "', scale=" + std::to_string(e.scale()) +
               ", visible=" + (e.visible() ? "True" : "False") + ")";
      });

  m.def(
      "sample_medium",
      [](const method::Model& model, int resolution) {
        method::MediumSamples s;
        {
          py::gil_scoped_release release;
          s = method::sample_medium(model, resolution);
        }
        py::dict d;
        d["sigma"] = volume(s.sigma, s.resolution, 1);
        d["albedo"] = volume(s.albedo, s.resolution, 3);
        d["g"] = volume(s.g, s.resolution, 1);
        return d;
      },
      py::arg("model"), py::arg("resolution") = 128,
      "The learned medium at the voxel centres of a resolution^3 grid over [-1, 1]^3: a dict of float32 arrays "
      "indexed [z, y, x]: 'sigma' (extinction per scene unit), 'albedo' (..., 3) and 'g'.");
  m.def(
      "export_vdb",
      [](const method::Model& model, const std::string& path, int resolution, float threshold, const std::string& run) {
        method::VdbExportSettings s;
        s.resolution = resolution;
        s.threshold = threshold;
        s.run = run;
        method::VdbExportStats stats;
        {
          py::gil_scoped_release release;
          stats = method::export_vdb(model, path, s);
        }
        py::dict d;
        d["active_voxels"] = stats.active_voxels;
        d["max_sigma"] = stats.max_sigma;
        d["mean_g"] = stats.mean_g;
        return d;
      },
      py::arg("model"), py::arg("path"), py::arg("resolution") = 128, py::arg("threshold") = 0.01f, py::arg("run") = "",
      "Writes the learned medium to an OpenVDB file (atomically): sparse grids 'density' (extinction per scene "
      "unit), 'albedo' and 'g' over the voxels with sigma above `threshold`, placed in the box [-1, 1]^3. "
      "Returns {'active_voxels', 'max_sigma', 'mean_g'}. relit.Scene.load_vdb / relit generate --scene read it.");
  m.def(
      "export_mitsuba",
      [](const method::Model& model, const std::string& dir, const Camera& camera, const py::object& light,
         int resolution, std::uint32_t spp, const std::string& run) {
        method::MitsubaExportSettings s;
        s.resolution = resolution;
        s.camera = camera;
        s.light = light_from(light);
        s.spp = spp;
        s.run = run;
        method::MitsubaExportStats stats;
        {
          py::gil_scoped_release release;
          stats = method::export_mitsuba(model, dir, s);
        }
        py::dict d;
        d["max_sigma"] = stats.max_sigma;
        d["mean_g"] = stats.mean_g;
        return d;
      },
      py::arg("model"), py::arg("dir"), py::arg("camera"), py::arg("light"), py::arg("resolution") = 128,
      py::arg("spp") = 256u, py::arg("run") = "",
      "Writes a Mitsuba 3 scene into the new folder `dir`: density.vol (extinction), albedo.vol and scene.xml (the "
      "medium in a null-BSDF cube, the camera, the point light, volpath). Returns {'max_sigma', 'mean_g'} (the "
      "scene's single HG g: the extinction-weighted mean).");
  m.def(
      "render_orbit",
      [](const method::Model& model, const std::string& prefix, int frames, const std::string& orbit,
         const py::object& eye, const py::object& target, const py::object& light, const py::object& intensity,
         int width, const py::object& height, float fov, std::uint32_t spp, int fps, bool mp4,
         const std::string& visibility) {
        if (orbit != "camera" && orbit != "light")
          throw InvalidArgument("orbit must be 'camera' or 'light', got '" + orbit + "'");
        method::Keyframe start{triple_from(eye, "eye"), triple_from(target, "target"), triple_from(light, "light"),
                               triple_from(intensity, "intensity")};
        const auto keys = orbit == "camera" ? method::orbit_camera(start, frames) : method::orbit_light(start, frames);
        return video(model, prefix, keys, width, height, fov, spp, fps, mp4, visibility);
      },
      py::arg("model"), py::arg("prefix"), py::arg("frames"), py::arg("orbit") = "light",
      py::arg("eye") = std::vector<float>{0, -4, 1}, py::arg("target") = std::vector<float>{0, 0, 0},
      py::arg("light") = std::vector<float>{0, -3, 3}, py::arg("intensity") = 600.0f, py::arg("width") = 128,
      py::arg("height") = py::none(), py::arg("fov") = 0.8f, py::arg("spp") = 1u, py::arg("fps") = 24,
      py::arg("mp4") = true, py::arg("visibility") = "",
      "A relighting video: `frames` frames of the camera (orbit='camera') or the light (orbit='light') going once "
      "around the vertical axis, written as PREFIX_0000.png ... and (mp4=True, through ffmpeg) PREFIX.mp4. "
      "Returns the frame paths.");
  m.def(
      "render_path",
      [](const method::Model& model, const std::string& prefix, const std::string& path, int width,
         const py::object& height, float fov, std::uint32_t spp, int fps, bool mp4, const std::string& visibility) {
        return video(model, prefix, method::read_keyframes(path), width, height, fov, spp, fps, mp4, visibility);
      },
      py::arg("model"), py::arg("prefix"), py::arg("path"), py::arg("width") = 128, py::arg("height") = py::none(),
      py::arg("fov") = 0.8f, py::arg("spp") = 1u, py::arg("fps") = 24, py::arg("mp4") = true,
      py::arg("visibility") = "",
      "A video along the keyframes of a JSON file (a list of {eye, target, light, intensity}; see relit render "
      "--path), written as render_orbit writes. Returns the frame paths.");
  m.def("presets", &method::preset_names,
        "Names of the built-in run configs (\"fast\", \"paper\", and per method \"bi-fast\", \"nerv-paper\", ...).");
  m.def("methods", &method::method_names, "Names of the methods a run config may choose (\"ours\", \"bi\", ...).");
  m.def(
      "preset", [](const std::string& name) { return json_to_python(method::preset(name)); }, py::arg("name"),
      "A built-in run config as a dict (edit it and pass it to relit.Trainer).");

  py::class_<method::TrainStats>(m, "TrainStats", "Where training stands (what `relit train` prints).")
      .def_readonly("step", &method::TrainStats::step)
      .def_readonly("target", &method::TrainStats::target)
      .def_readonly("loss", &method::TrainStats::loss, "render loss of the last step")
      .def_readonly("visibility_loss", &method::TrainStats::visibility_loss)
      .def_readonly("val_psnr", &method::TrainStats::val_psnr, "last validation PSNR in dB (nan before any)")
      .def_readonly("steps_per_second", &method::TrainStats::steps_per_second)
      .def_readonly("elapsed", &method::TrainStats::elapsed, "seconds")
      .def_readonly("eta", &method::TrainStats::eta, "seconds")
      .def_readonly("learning_rate", &method::TrainStats::learning_rate)
      .def_readonly("skipped", &method::TrainStats::skipped, "steps skipped for a non-finite loss")
      .def("__repr__", [](const method::TrainStats& s) {
        return "TrainStats(step=" + std::to_string(s.step) + ", loss=" + std::to_string(s.loss) +
               ", val_psnr=" + std::to_string(s.val_psnr) + ")";
      });

  py::class_<method::Model>(m, "Model",
                            "A trained relightable model (any method of relit.methods()): renders any camera under any "
                            "point light.")
      .def_static(
          "load",
          [](const std::string& path, const py::object& device) {
            return method::load_model(device_arg(device), path);
          },
          py::arg("path"), py::arg("device") = py::none(), "Loads the model of a checkpoint (checkpoint.relit).")
      .def(
          "render", &render, py::arg("camera"), py::arg("light"), py::arg("visibility") = "", py::arg("seed") = 0,
          py::arg("environment") = py::none(), py::arg("spp") = 1,
          "Renders camera's image under the point light: float32 (height, width, 3), linear RGB. visibility:\n"
          "\"network\" or \"march\" (default: the model's setting). environment: a relit.EnvironmentLight\n"
          "lighting the scene as well (models trained on 'env+point' data), e.g. EnvironmentLight.from_dataset(path).\n"
          "spp: rays per pixel, averaged over an n x n grid in each pixel (1, 4, 9, ...).")
      .def_property_readonly(
          "has_environment", [](const method::Model& o) { return o.has_environment(); },
          "whether the model was trained with an environment light ('env+point' data)")
      .def_property_readonly("method", &method::Model::method, "the method: \"ours\", \"bi\" or \"nerv\"")
      .def_property_readonly("n_params", &method::Model::n_params)
      .def_property_readonly("n_visibility_params", &method::Model::n_vis_params)
      .def(
          "parameters", [](method::Model& o) { return vector_array(o.params().read()); },
          "A copy of θ (the property net, the SH head, ...): float32, n_params values.")
      .def(
          "visibility_parameters", [](method::Model& o) { return vector_array(o.vis_params().read()); },
          "A copy of ψ (the visibility net): float32, n_visibility_params values.")
      .def_property_readonly("config", [](const method::Model& o) { return json_to_python(o.hyperparams()); });

  py::class_<RunIterator>(m, "_RunIterator")
      .def("__iter__", [](RunIterator& it) -> RunIterator& { return it; })
      .def("__next__", &RunIterator::next);

  py::class_<method::Trainer>(m, "Trainer", "Trains the model on a dataset folder (relit train in Python).")
      .def(py::init([](const std::string& dataset, const py::object& config, const py::object& out,
                       const py::object& device, const py::object& method) {
             auto t = std::make_unique<method::Trainer>(device_arg(device), dataset, config_from(config, method));
             if (!out.is_none()) t->set_output(out.cast<std::string>());
             return t;
           }),
           py::arg("dataset"), py::arg("config") = "fast", py::arg("out") = py::none(), py::arg("device") = py::none(),
           py::arg("method") = py::none(),
           "config: a preset name, a .json path or a dict. method: \"ours\" (default), \"ours_brdf\", \"bi\" or\n"
           "\"nerv\" (with a preset name, that method's preset: bi-fast, ...). out: a run folder for config.json,\n"
           "log.jsonl and checkpoints (optional).")
      .def(
          "run",
          [](method::Trainer& t, std::uint64_t n, std::uint64_t every) {
            return RunIterator{&t, t.steps() + n, every ? every : t.settings().log_every};
          },
          py::arg("n"), py::arg("every") = 0, py::keep_alive<0, 1>(),
          "Trains n more steps, yielding TrainStats every `every` steps (default: training.log_every).")
      .def("step", &method::Trainer::step, "One training step (asynchronous).")
      .def("stats", &method::Trainer::stats)
      .def("validate", &method::Trainer::validate, py::call_guard<py::gil_scoped_release>(),
           "Mean PSNR (dB) of the validation views.")
      .def("profile", &method::Trainer::profile, py::arg("n") = 10, py::call_guard<py::gil_scoped_release>(),
           "Mean milliseconds per stage of a step over n steps: [(stage, ms), ...].")
      .def("save_checkpoint", &method::Trainer::save_checkpoint, py::arg("path"))
      .def("load_checkpoint", &method::Trainer::load_checkpoint, py::arg("path"))
      .def_property_readonly("steps", &method::Trainer::steps)
      .def_property_readonly("config", [](const method::Trainer& t) { return json_to_python(t.config()); })
      .def_property_readonly(
          "model", [](method::Trainer& t) -> method::Model& { return t.model(); },
          py::return_value_policy::reference_internal);
}

}  // namespace relit::python
