// Writes the checkpoint seeds of corpus/checkpoint/ with the library's own writer (run once; the outputs are
// committed). Build against a build tree, e.g.:
//   c++ -std=c++17 make_checkpoint_seeds.cpp -I../../lib/include -I../../build/lib/generated/include \
//       -L../../build/lib -lrelit -o make_checkpoint_seeds && LD_LIBRARY_PATH=../../build/lib ./make_checkpoint_seeds
#include <relit/io/checkpoint.hpp>

int main() {
  relit::io::Checkpoint tiny;
  tiny.header["step"] = 3;
  tiny.tensors["params"] = {0.5f, -1.0f, 2.0f};
  tiny.tensors["vis_params"] = {1.0f};
  relit::io::save_checkpoint("corpus/checkpoint/tiny.relit", tiny);

  relit::io::save_checkpoint("corpus/checkpoint/no-tensors.relit", relit::io::Checkpoint{});

  relit::io::Checkpoint run;
  run.header["config"] = {{"method", "ours"}, {"training", {{"steps", 10}}}};
  run.header["step"] = 10;
  run.header["rng"] = {1, 2, 3};
  run.tensors["adam.m"] = std::vector<float>(4, 0.0f);
  run.tensors["adam.v"] = std::vector<float>(4, 1e-8f);
  run.tensors["empty"] = {};
  relit::io::save_checkpoint("corpus/checkpoint/run.relit", run);
  return 0;
}
