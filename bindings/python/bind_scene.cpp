// Python binding of scenes, the reference path tracer and dataset generation:
//   scene = relit.Scene.builtin("cloud")            # or Scene.load("scene.json"), Scene.from_json({...})
//   img = relit.render_reference(scene, camera, lights=[relit.PointLight((0, -3, 3), 600)], spp=64)  # (H, W, 4)
//   relit.generate_dataset(scene, "out", lighting="point", train=100, progress=lambda p: print(p.eta))
// Long calls release the GIL; progress callables get a relit.Progress and may return False to cancel.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "bindings.hpp"
#include "convert.hpp"

#include <relit/dataset.hpp>
#include <relit/pathtrace.hpp>
#include <relit/scene/scene.hpp>

namespace py = pybind11;

namespace relit::python {

void bind_scene(py::module_& m) {
  py::class_<Progress>(m, "Progress", "Progress of a long operation, passed to progress callbacks.")
      .def_readonly("done", &Progress::done)
      .def_readonly("total", &Progress::total)
      .def_readonly("elapsed", &Progress::elapsed, "seconds")
      .def_readonly("rate", &Progress::rate, "units per second")
      .def_readonly("eta", &Progress::eta, "seconds left")
      .def_readonly("unit", &Progress::unit)
      .def_readonly("message", &Progress::message)
      .def_property_readonly("fraction", &Progress::fraction)
      .def("__repr__", [](const Progress& p) {
        return "<relit.Progress " + std::to_string(p.done) + "/" + std::to_string(p.total) + " " + p.unit + ">";
      });

  py::class_<PointLight>(m, "PointLight", "A point light: position and RGB radiant intensity (W/sr).")
      .def(py::init([](const Float3& position, const py::object& intensity) {
             PointLight l;
             l.position = position;
             if (py::isinstance<py::float_>(intensity) || py::isinstance<py::int_>(intensity))
               l.intensity.fill(intensity.cast<float>());
             else
               l.intensity = intensity.cast<Float3>();
             l.validate();
             return l;
           }),
           py::arg("position"), py::arg("intensity") = 600.0f)
      .def_readwrite("position", &PointLight::position)
      .def_readwrite("intensity", &PointLight::intensity);

  py::class_<Camera>(m, "Camera",
                     "A pinhole camera (camera-to-world in OpenGL/Blender axes, camera_angle_x in radians).")
      .def_static("look_at", &Camera::look_at, py::arg("eye"), py::arg("target") = Float3{0, 0, 0},
                  py::arg("up") = Float3{0, 0, 1}, py::arg("camera_angle_x") = 0.8f, py::arg("width") = 128,
                  py::arg("height") = 128)
      .def_readwrite("transform", &Camera::transform, "4x4 camera-to-world, row-major")
      .def_readwrite("camera_angle_x", &Camera::camera_angle_x)
      .def_readwrite("width", &Camera::width)
      .def_readwrite("height", &Camera::height)
      .def_property_readonly("position", &Camera::position);

  py::class_<Scene>(m, "Scene", "A scene for the reference path tracer (see docs/scenes.md).")
      .def_static(
          "builtin",
          [](const std::string& name, unsigned seed, int resolution) {
            return Scene::from_json(Scene::builtin_json(name, seed, resolution));
          },
          py::arg("name"), py::arg("seed") = 0, py::arg("resolution") = 64,
          "A built-in scene: cloud, smoke, blobs, spheres or torus.")
      .def_static("load", &Scene::load, py::arg("path"), py::call_guard<py::gil_scoped_release>())
      .def_static(
          "from_json",
          [](const py::object& obj, const std::string& base_dir) {
            const Json j = py::isinstance<py::str>(obj) ? parse_json(obj.cast<std::string>(), "the scene string")
                                                        : json_from_python(obj);
            py::gil_scoped_release release;
            return Scene::from_json(j, base_dir);
          },
          py::arg("description"), py::arg("base_dir") = ".", "From a dict or a JSON string.")
      .def_static("builtin_names", &Scene::builtin_names)
      .def_property_readonly(
          "description", [](const Scene& s) { return json_to_python(s.description); },
          "the resolved JSON description (a dict)")
      .def_readwrite("cameras", &Scene::cameras)
      .def_readwrite("lights", &Scene::lights)
      .def_property_readonly("has_medium", [](const Scene& s) { return s.medium.has_value(); })
      .def_property_readonly(
          "medium_density",
          [](const Scene& s) -> py::object {
            if (!s.medium) return py::none();
            const Grid& g = s.medium->density;
            py::array_t<float> a({g.nz, g.ny, g.nx});
            std::copy(g.values.begin(), g.values.end(), a.mutable_data());
            return std::move(a);
          },
          "the medium's density grid (before density_scale) as float32 (nz, ny, nx), voxel-centred over the box\n"
          "[-1, 1]^3, x fastest; None without a medium")
      .def_property_readonly("has_solid", [](const Scene& s) { return s.solid.has_value(); })
      .def_property_readonly("has_environment", [](const Scene& s) { return s.environment.has_value(); });

  m.def(
      "render_reference",
      [](const Scene& scene, const py::object& camera, const py::object& lights, std::uint32_t spp, std::uint32_t seed,
         std::uint32_t max_bounces, const py::object& device, const py::object& progress,
         bool with_variance) -> py::object {
        Camera cam;
        if (camera.is_none()) {
          if (scene.cameras.empty())
            throw InvalidArgument("the scene has no camera; pass camera=relit.Camera.look_at(...)");
          cam = scene.cameras[0];
        } else if (py::isinstance<py::int_>(camera)) {
          const auto i = camera.cast<std::size_t>();
          if (i >= scene.cameras.size()) throw InvalidArgument("camera index " + std::to_string(i) + " out of range");
          cam = scene.cameras[i];
        } else {
          cam = camera.cast<Camera>();
        }
        const std::vector<PointLight> ls = lights.is_none() ? scene.lights : lights.cast<std::vector<PointLight>>();
        PathTraceSettings rs;
        rs.spp = spp, rs.seed = seed, rs.max_bounces = max_bounces;
        const Device dev = device_arg(device);
        const ProgressCallback cb = progress_arg(progress);
        RenderResult r;
        {
          py::gil_scoped_release release;
          r = PathTracer(dev, scene).render(cam, ls, rs, cb);
        }
        if (with_variance) return py::make_tuple(image_to_numpy(r.image), image_to_numpy(r.variance));
        return image_to_numpy(r.image);
      },
      py::arg("scene"), py::arg("camera") = py::none(), py::arg("lights") = py::none(), py::arg("spp") = 64,
      py::arg("seed") = 0, py::arg("max_bounces") = 0, py::arg("device") = py::none(), py::arg("progress") = py::none(),
      py::arg("with_variance") = false,
      "Path-traces one view; returns a float32 array (height, width, 4): linear RGB and alpha. camera: a Camera,\n"
      "an index into scene.cameras, or None (the first). lights: PointLights (default: the scene's).\n"
      "with_variance=True also returns the per-pixel variance of one sample.");

  m.def(
      "generate_dataset",
      [](const Scene& scene, const std::string& out, const std::string& lighting, std::uint32_t seed, int resolution,
         std::uint32_t train, std::uint32_t val, std::uint32_t test, std::uint32_t spp, const py::object& intensity,
         bool generalization, bool overwrite, bool previews, const py::object& device, const py::object& progress,
         std::uint32_t test_spp) {
        DatasetSettings s;
        s.lighting = lighting, s.seed = seed, s.resolution = resolution, s.train = train, s.val = val, s.test = test;
        s.spp = spp, s.test_spp = test_spp, s.generalization = generalization, s.overwrite = overwrite,
        s.previews = previews;
        if (py::isinstance<py::float_>(intensity) || py::isinstance<py::int_>(intensity)) {
          s.intensity_min = s.intensity_max = intensity.cast<float>();
        } else {
          const auto range = intensity.cast<std::vector<float>>();
          if (range.size() != 2) throw InvalidArgument("intensity must be a number or a (min, max) pair");
          s.intensity_min = range[0], s.intensity_max = range[1];
        }
        const Device dev = device_arg(device);
        const ProgressCallback cb = progress_arg(progress);
        py::gil_scoped_release release;
        generate_dataset(dev, scene, out, s, cb);
      },
      py::arg("scene"), py::arg("out"), py::arg("lighting") = "point", py::arg("seed") = 0, py::arg("resolution") = 128,
      py::arg("train") = 100, py::arg("val") = 20, py::arg("test") = 50, py::arg("spp") = 64,
      py::arg("intensity") = 600.0f, py::arg("generalization") = false, py::arg("overwrite") = false,
      py::arg("previews") = true, py::arg("device") = py::none(), py::arg("progress") = py::none(),
      py::arg("test_spp") = 0,
      "Renders a dataset folder (docs/dataset-format.md). lighting: 'point' or 'env+point'; intensity: W/sr, or a\n"
      "(min, max) range; test_spp: samples per pixel of the test splits (0: spp). The folder appears only when\n"
      "complete.");
}

}  // namespace relit::python
