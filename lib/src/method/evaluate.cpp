// relit eval: render the test views, compare, write the report (relit/report.hpp).
#include <relit/method/evaluate.hpp>
#include <relit/dataset.hpp>
#include <relit/method/render_image.hpp>
#include <relit/metrics.hpp>

#include <cstdint>

namespace relit::method {

std::vector<report::ViewResult> evaluate(const Model& model, const std::string& dataset_dir, const std::string& out_dir,
                                         const EvalOptions& options, const Json& meta,
                                         const ProgressCallback& progress) {
  if (options.splits.empty()) throw InvalidArgument("evaluate: no splits given");
  std::vector<DatasetSplit> splits;
  std::size_t total = 0;
  for (const auto& name : options.splits) {
    splits.push_back(load_split(dataset_dir, name, options.max_views));
    total += splits.back().size();
  }
  std::vector<report::ViewResult> views;
  ProgressTracker tracker(progress, total, "views");
  ImageRenderSettings rs;
  rs.visibility = options.visibility;
  rs.spp = options.spp;
  for (const auto& split : splits)
    for (std::size_t i = 0; i < split.size(); ++i) {
      report::ViewResult v;
      v.split = split.split;
      v.name = split.names[i];
      v.width = static_cast<std::uint32_t>(split.width);
      v.height = static_cast<std::uint32_t>(split.height);
      rs.seed = static_cast<std::uint32_t>(i);
      rs.environment = split.environment.get();
      Image img = render_image(model, split.cameras[i], split.lights[i], rs);
      v.prediction = std::move(img.pixels);
      v.reference = split.image(i);
      v.metrics = metrics::compare(model.device(), v.prediction, v.reference, v.width, v.height, 3);
      views.push_back(std::move(v));
      tracker.update(views.size(), split.split + "/" + split.names[i]);
    }
  report::ReportOptions ro;
  ro.meta = meta;
  ro.write_predictions = ro.write_exr = options.write_images;
  report::write_report(out_dir, views, ro);
  return views;
}

}  // namespace relit::method
