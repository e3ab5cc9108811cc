// relit eval: render the test views, compare, write the report (relit/report.hpp).
#include <relit/method/evaluate.hpp>
#include <relit/dataset.hpp>
#include <relit/method/render_image.hpp>
#include <relit/metrics.hpp>
#include <relit/parallel.hpp>

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
  // Every view in order; under MPI they are shared out over the ranks and rank 0 compares and writes the report
  // (relit/parallel.hpp): each view is rendered with its own seed, so the report is the single-process one.
  std::vector<std::pair<const DatasetSplit*, std::size_t>> order;
  for (const auto& split : splits)
    for (std::size_t i = 0; i < split.size(); ++i) order.emplace_back(&split, i);
  const bool writer = parallel::rank() == 0;
  std::vector<report::ViewResult> views;
  ProgressTracker tracker(writer ? progress : ProgressCallback(), total, "views");
  ImageRenderSettings rs;
  rs.visibility = options.visibility;
  rs.spp = options.spp;
  rs.alpha = true;  // the object mask of the metrics (the prediction's alpha or the reference's)
  const auto render = [&](std::size_t k) {
    const auto& [split, i] = order[k];
    rs.seed = static_cast<std::uint32_t>(i);
    rs.environment = split->environment.get();
    return render_image(model, split->cameras[i], split->lights[i], rs).pixels;
  };
  const auto compare = [&](std::size_t k, std::vector<float>&& rgba) {
    const auto& [split, i] = order[k];
    Image image(split->width, split->height, 4);
    image.pixels = std::move(rgba);
    auto [prediction, alpha] = split_rgb_alpha(image);
    report::ViewResult v;
    v.split = split->split;
    v.name = split->names[i];
    v.width = static_cast<std::uint32_t>(split->width);
    v.height = static_cast<std::uint32_t>(split->height);
    v.prediction = std::move(prediction);
    v.reference = split->image(i);
    const auto mask = metrics::object_mask(split->alpha(i), alpha, alpha.size());
    v.prediction_alpha = std::move(alpha);
    v.metrics = metrics::compare(model.device(), v.prediction, v.reference, v.width, v.height, 3, &mask);
    views.push_back(std::move(v));
    tracker.update(views.size(), split->split + "/" + split->names[i]);
  };
  const auto view_size = [&](std::size_t k) { return std::size_t(order[k].first->width) * order[k].first->height * 4; };
  parallel::share_out(order.size(), view_size, render, compare);
  if (!writer) return views;  // rank 0 holds the results and writes the report
  report::ReportOptions ro;
  ro.meta = meta;
  ro.write_predictions = ro.write_exr = options.write_images;
  report::write_report(out_dir, views, ro);
  return views;
}

}  // namespace relit::method
