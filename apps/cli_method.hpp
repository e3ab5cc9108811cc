// relit train and relit eval as functions, shared by their commands and by relit demo, which chains them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace relit::cli {

struct TrainOptions {
  std::string dataset, config = "fast", out, device, method;
  std::optional<long long> steps, seed;  // unset: the config's training.steps and training.seed
  double minutes = 0;
  bool resume = false;
  unsigned profile = 0;
};

/// Trains (or resumes, or profiles) a run as `relit train` does; returns the exit code.
int run_train(const TrainOptions& o);

struct EvalOptions {
  std::string run, dataset, out, device, visibility;
  std::string predictions, references;  ///< compare two folders of images instead of rendering a run
  std::vector<std::string> splits;
  std::size_t max_views = 0;
  std::uint32_t spp = 1;
  bool no_images = false;
};

/// Relights a run's test views and writes its report as `relit eval` does; returns the exit code.
int run_eval(const EvalOptions& o);

}  // namespace relit::cli
