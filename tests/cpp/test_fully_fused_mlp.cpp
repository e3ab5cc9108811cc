// FullyFusedMLP against a double-precision Eigen reference: forward, dL/dinput and dL/dparams for every
// width, with and without skips, biases and heads, several batch sizes; central finite differences; the
// accumulate flag; bit-for-bit determinism; config errors.
#include "test_support.hpp"
#include <relit/verify/mlp_reference.hpp>

#include <relit/nn/fully_fused_mlp.hpp>
#include <relit/nn/network_with_encoding.hpp>
#include <relit/nn/registry.hpp>

#include <Eigen/Dense>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>

namespace relit::nn {
namespace {

using reference::flatten;
using reference::Mat;
using reference::to_mat;
using reference::worst_ratio;
using Reference = reference::MlpReference;

std::unique_ptr<FullyFusedMLP> make_mlp(const Json& config, std::uint32_t n_in, std::uint32_t n_out) {
  auto net = create_network(config, n_in, n_out);
  auto* mlp = dynamic_cast<FullyFusedMLP*>(net.get());
  EXPECT_NE(mlp, nullptr);
  net.release();
  return std::unique_ptr<FullyFusedMLP>(mlp);
}

using reference::random_vector;

using Blocking = FullyFusedMLP::Blocking;
using WorkGroupParams = FullyFusedMLP::WorkGroupParams;

// Work-group parameters that every device must run alike: the NVIDIA row of the table (128-sample tiles of
// 256 work-items, lowered to fit local memory where it is small), and odd sizes: 48-sample tiles, 40
// work-items, 3 x 6 register blocks and 5-column weight slices that divide nothing, 12 x 12 dW tiles staged 7
// samples at a time, and 112-sample dW chunks, so that a batch of a few hundred samples has several partials.
const WorkGroupParams kWgNvidia{128, 256, 4, 4, 16, 64, 4, 16, 512};
const WorkGroupParams kWgOdd{48, 40, 3, 6, 5, 12, 3, 7, 112};

// The kernel variants the small-network tests run: the device's choice ("auto") and each variant forced.
void use_variant(FullyFusedMLP& net, const std::string& variant) {
  if (variant == "simd") net.set_blocking(Blocking{});
  if (variant == "workgroup") net.set_workgroup(kWgOdd);
}

struct Case {
  const char* name;
  std::uint32_t n_in, n_out;
  Json config;
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

std::vector<Case> cases() {
  return {
      {"w16_L1", 3, 1, {{"n_neurons", 16}, {"n_hidden_layers", 1}}},
      {"w32_L2_skip_heads",
       7,
       6,
       {{"n_neurons", 32},
        {"n_hidden_layers", 2},
        {"skip_layers", {1}},
        {"output_heads",
         {{{"n_dims", 1}, {"activation", "Softplus"}},
          {{"n_dims", 3}, {"activation", "Sigmoid"}},
          {{"n_dims", 1}, {"activation", "Tanh"}},
          {{"n_dims", 1}, {"activation", "None"}}}}}},
      {"w64_L3_small_net", 32, 16, {{"n_neurons", 64}, {"n_hidden_layers", 3}, {"output_activation", "ReLU"}}},
      {"w128_L2_skip_sigmoid",
       19,
       4,
       {{"n_neurons", 128}, {"n_hidden_layers", 2}, {"skip_layers", {1}}, {"output_activation", "Sigmoid"}}},
      {"w256_L3_skip_nobias",
       63,
       16,
       {{"n_neurons", 256}, {"n_hidden_layers", 3}, {"skip_layers", {2}}, {"bias", false}}},
      {"w64_L4_linear_heads_2skips",
       5,
       9,
       {{"n_neurons", 64},
        {"n_hidden_layers", 4},
        {"activation", "None"},
        {"skip_layers", {1, 3}},
        {"bias", false},
        {"output_heads", {{{"n_dims", 2}, {"activation", "Tanh"}}, {{"n_dims", 7}, {"activation", "Softplus"}}}}}},
  };
}

class MlpCase : public ::testing::TestWithParam<Case> {};

TEST_P(MlpCase, ForwardAndBackwardMatchReference) {
  const Case& c = GetParam();
  const Device device = test::test_device();
  auto net = make_mlp(c.config, c.n_in, c.n_out);
  // The network's parameters sit at an offset inside a larger model buffer, as in a real model.
  const std::size_t offset = 37, np = net->n_params();
  std::vector<float> params(offset + np + 11, 0.5f);
  net->initialize_params(params.data() + offset, 7);
  // Random non-zero biases, so that they are tested (initialisation sets them to zero).
  if (net->has_bias()) {
    auto r = random_vector(np, 99, -0.3f, 0.3f);
    for (std::uint32_t l = 0; l <= net->n_hidden_layers(); ++l) {
      const std::uint32_t n_in = net->layer_inputs(l);
      for (std::uint32_t j = 0; j < net->layer_outputs(l); ++j) {
        const std::size_t i = offset + net->layer_offset(l) + std::size_t(j) * (n_in + 1) + n_in;
        params[i] = r[i - offset];
      }
    }
  }
  Buffer<float> pbuf(device, params);
  Buffer<float> gbuf(device, params.size());
  Reference ref(*net, params, offset);

  // The device's choice, and kernels that every device must run alike. The SIMD variant with the AVX2/GPU and
  // AVX-512 register blockings and odd sizes (3 tiles per work-item, blocks that do not divide the widths),
  // each with the separate backward kernels and with the fused training kernel (forced for every network
  // size), and the outer-product weight gradients (dw_vector 1) with the Intel row's blocks and odd ones (every
  // count of last column vectors, rows that do not divide the layers, several row regions), the fused kernel
  // also reading the saved activations (train_saved: groups of 3 tiles, so that the last one is short); the work-group
  // variant with the NVIDIA row's parameters and odd ones (kWgOdd).
  constexpr std::uint32_t kAlways = 1u << 30;
  struct Kernels {
    std::optional<Blocking> blocking;
    std::optional<WorkGroupParams> workgroup;
  };
  // A pair of blockings that differ only in fused_train_max_params (chosen on the host) has the same train_group,
  // which only the fused kernel reads: both then run one program, built once (kernel builds are most of these
  // tests' time).
  std::vector<Kernels> variants = {{},
                                   {Blocking{1, 4, 4, 8, 4, 3, 16, 0, 5}, {}},
                                   {Blocking{1, 4, 4, 8, 4, 3, 16, kAlways, 5}, {}},
                                   {Blocking{2, 8, 8, 16, 4, 4, 16, 0}, {}},
                                   {Blocking{2, 8, 8, 16, 4, 4, 16, kAlways}, {}},
                                   {Blocking{3, 5, 3, 16, 3, 5, 9, 0, 3}, {}},
                                   {Blocking{3, 5, 3, 16, 3, 5, 9, kAlways, 3}, {}},
                                   {Blocking{4, 6, 6, 1, 8, 3, 256, 0, 16}, {}},
                                   {Blocking{4, 6, 6, 1, 8, 3, 256, kAlways, 16}, {}},
                                   {Blocking{1, 4, 4, 1, 5, 4, 10, 0, 3}, {}},
                                   {Blocking{1, 4, 4, 1, 5, 4, 10, kAlways, 3}, {}},
                                   {Blocking{1, 4, 4, 1, 5, 4, 10, kAlways, 3, true}, {}},
                                   {Blocking{2, 5, 3, 1, 3, 2, 9, 0}, {}}};
  // PoCL's build of a work-group program grows with the group's size: for the 256-wide network the NVIDIA row's
  // 256 work-items take minutes on 2 cores, and the odd sizes' 40 about 65 s against 25 s for 7 items, so that
  // network runs the odd sizes with 7 items (the narrower ones cover groups of 40, with items left idle).
  WorkGroupParams odd = kWgOdd;
  if (net->width() == 256)
    odd.items = 7;
  else
    variants.push_back({{}, kWgNvidia});
  variants.push_back({{}, odd});
  // Inputs and the double reference per batch size (d_output rows beyond the batch hold garbage, 16 extra
  // rows: the kernels must ignore them).
  struct BatchCase {
    std::uint32_t batch, garbage_rows;
    std::vector<float> xh, dyh;
    Mat want_y, want_dx;
    std::vector<double> want_dp;
  };
  std::vector<BatchCase> batches;
  // On Oclgrind (test::tiny_sizes()) the small batches only: a partial tile and a single sample.
  const std::vector<std::uint32_t> batch_sizes =
      test::tiny_sizes() ? std::vector<std::uint32_t>{33u, 1u} : std::vector<std::uint32_t>{1000u, 100u, 96u, 33u, 1u};
  for (std::uint32_t batch : batch_sizes) {
    BatchCase b{batch, batch < 1000 ? 16u : 0u, random_vector(std::size_t(batch) * c.n_in, batch + 1), {}, {}, {}, {}};
    b.dyh = random_vector(std::size_t(batch + b.garbage_rows) * c.n_out, batch + 2);
    for (std::size_t i = std::size_t(batch) * c.n_out; i < b.dyh.size(); ++i) b.dyh[i] = 1e3f;
    const Mat xm = to_mat(b.xh, batch, c.n_in);
    b.want_y = ref.forward(xm);
    ref.backward(xm, to_mat(b.dyh, batch, c.n_out), b.want_dp, b.want_dx);
    batches.push_back(std::move(b));
  }
  for (const Kernels& variant : variants) {
    if (variant.workgroup)
      net->set_workgroup(variant.workgroup);
    else
      net->set_blocking(variant.blocking);
    // One workspace and one set of matrices for every batch size: sized by the first, reused by the smaller.
    auto ws = net->make_workspace(device);
    BatchMatrix x(device, 1000, c.n_in), y(device, 1000, c.n_out), dy(device, 1000, c.n_out), dx(device, 1000, c.n_in);
    for (const BatchCase& b : batches) {
      SCOPED_TRACE(std::string(c.name) + " batch " + std::to_string(b.batch) + " kernels " +
                   net->kernel_choice(device).str());
      x.resize(b.batch);
      x.upload_row_major(b.xh);
      dy.resize(b.batch + b.garbage_rows);
      dy.upload_row_major(b.dyh);
      dy.resize(b.batch);

      BatchMatrix yi(device, 1, c.n_out);
      net->inference(device, {&pbuf, offset}, x, yi);
      EXPECT_LE(worst_ratio(yi.download_row_major(), flatten(b.want_y), 1e-5), 1.0) << "inference";

      net->forward(device, {&pbuf, offset}, x, y, *ws);
      EXPECT_LE(worst_ratio(y.download_row_major(), flatten(b.want_y), 1e-5), 1.0) << "training forward";

      gbuf.fill(std::nanf(""));  // overwritten (accumulate = false), outside the slice untouched
      net->backward(device, {&pbuf, offset}, x, y, dy, {&gbuf, offset}, false, &dx, *ws);
      const auto g = gbuf.read();
      EXPECT_LE(worst_ratio(g.data() + offset, b.want_dp, 1e-4), 1.0) << "dL/dparams";
      EXPECT_TRUE(std::isnan(g[offset - 1]) && std::isnan(g[offset + np])) << "wrote outside its gradient slice";
      EXPECT_LE(worst_ratio(dx.download_row_major(), flatten(b.want_dx), 1e-4), 1.0) << "dL/dinput";
    }
  }
}

// The outer-product weight gradients walk a chunk of the batch in blocks of 512 samples and add each block to
// the work-item's dW rows: a batch whose chunks hold a full and a partial block (600 samples per chunk on any
// device: the backward pass cuts the batch into 8 chunks per compute unit).
TEST(FullyFusedMLP, OuterProductGradientsAddUpSeveralBlocksOfSamples) {
  const Device device = test::test_device();
  for (const Blocking& blocking : {Blocking{4, 6, 6, 1, 8, 3, 256, 0}, Blocking{2, 5, 3, 1, 3, 2, 9, 0}}) {
    // Linear hidden layers: over thousands of samples some ReLU input would lie within float rounding of zero,
    // where the double reference may take the other side of the kink.
    auto net =
        make_mlp({{"n_neurons", 16}, {"n_hidden_layers", 2}, {"skip_layers", {1}}, {"activation", "None"}}, 7, 3);
    net->set_blocking(blocking);
    std::vector<float> params(net->n_params());
    net->initialize_params(params.data(), 11);
    const auto r = random_vector(params.size(), 12, -0.2f, 0.2f);
    for (std::size_t i = 0; i < params.size(); ++i) params[i] += r[i];
    const std::uint32_t batch = 600 * 8 * std::max(1u, device.info().compute_units);
    const auto xh = random_vector(std::size_t(batch) * 7, 13), dyh = random_vector(std::size_t(batch) * 3, 14);
    Reference ref(*net, params, 0);
    std::vector<double> want_dp;
    Mat want_dx;
    const Mat xm = to_mat(xh, batch, 7);
    ref.forward(xm);
    ref.backward(xm, to_mat(dyh, batch, 3), want_dp, want_dx);

    Buffer<float> pbuf(device, params), gbuf(device, params.size());
    BatchMatrix x(device, batch, 7), y(device, batch, 3), dy(device, batch, 3);
    x.upload_row_major(xh);
    dy.upload_row_major(dyh);
    auto ws = net->make_workspace(device);
    net->forward(device, {&pbuf, 0}, x, y, *ws);
    net->backward(device, {&pbuf, 0}, x, y, dy, {&gbuf, 0}, false, nullptr, *ws);
    EXPECT_FALSE(net->fused_training(device));
    EXPECT_LE(worst_ratio(gbuf.read(), want_dp, 1e-4), 1.0) << blocking.str();
  }
}

// The fused training kernel reading the saved activations (train_saved) does the recomputing kernel's
// operations in the same order on the same values: its gradients are the same bit for bit (so the device row
// that switched to it trains exactly as before). A ReLU network with a skip, a batch whose last group of tiles
// is short, dL/dinput wanted.
TEST(FullyFusedMLP, SavedActivationsGiveTheRecomputedGradientsBitForBit) {
  const Device device = test::test_device();
  const std::uint32_t n_in = 7, n_out = 3, batch = 16 * 97 + 5;
  const auto xh = random_vector(std::size_t(batch) * n_in, 21), dyh = random_vector(std::size_t(batch) * n_out, 22);
  for (const std::uint32_t group : {3u, 4u}) {
    std::vector<std::vector<float>> grads, dxs;
    for (const bool saved : {false, true}) {
      auto net = make_mlp({{"n_neurons", 32}, {"n_hidden_layers", 3}, {"skip_layers", {2}}}, n_in, n_out);
      net->set_blocking(Blocking{1, 4, 4, 1, 5, 4, 10, 1u << 30, group, saved});
      std::vector<float> params(net->n_params());
      net->initialize_params(params.data(), 23);
      Buffer<float> pbuf(device, params), gbuf(device, params.size());
      BatchMatrix x(device, batch, n_in), y(device, batch, n_out), dy(device, batch, n_out), dx(device, batch, n_in);
      x.upload_row_major(xh);
      dy.upload_row_major(dyh);
      auto ws = net->make_workspace(device);
      net->forward(device, {&pbuf, 0}, x, y, *ws);
      net->backward(device, {&pbuf, 0}, x, y, dy, {&gbuf, 0}, false, &dx, *ws);
      EXPECT_TRUE(net->fused_training(device));
      grads.push_back(gbuf.read());
      dxs.push_back(dx.download_row_major());
    }
    EXPECT_EQ(grads[0], grads[1]) << "groups of " << group;
    EXPECT_EQ(dxs[0], dxs[1]) << "groups of " << group;
  }
}

INSTANTIATE_TEST_SUITE_P(FullyFusedMLP, MlpCase, ::testing::ValuesIn(cases()),
                         [](const auto& info) { return std::string(info.param.name); });

// A shared small network for the remaining tests: skip, bias, smooth heads.
struct Small {
  Device device = test::test_device();
  std::unique_ptr<FullyFusedMLP> net;
  std::vector<float> params;
  Small(const Json& extra = Json::object(), std::uint32_t n_in = 5, std::uint32_t n_out = 4) {
    Json cfg = {{"n_neurons", 16},
                {"n_hidden_layers", 3},
                {"skip_layers", {2}},
                {"output_heads",
                 {{{"n_dims", 1}, {"activation", "Softplus"}},
                  {{"n_dims", 2}, {"activation", "Sigmoid"}},
                  {{"n_dims", 1}, {"activation", "Tanh"}}}}};
    cfg.update(extra);
    net = make_mlp(cfg, n_in, n_out);
    params.resize(net->n_params());
    net->initialize_params(params.data(), 3);
    auto r = random_vector(params.size(), 5, -0.2f, 0.2f);
    for (std::size_t i = 0; i < params.size(); ++i) params[i] += r[i];  // non-zero biases too
  }
};

// The small-network tests run with the device's choice and with each variant forced.
class MlpVariant : public ::testing::TestWithParam<std::string> {};

TEST_P(MlpVariant, AccumulateAddsToGradients) {
  Small s;
  use_variant(*s.net, GetParam());
  const std::uint32_t batch = 300;
  Buffer<float> pbuf(s.device, s.params);
  BatchMatrix x(s.device, batch, 5), y(s.device, batch, 4), dy(s.device, batch, 4);
  x.upload_row_major(random_vector(batch * 5, 1));
  dy.upload_row_major(random_vector(batch * 4, 2));
  auto ws = s.net->make_workspace(s.device);
  s.net->forward(s.device, {&pbuf, 0}, x, y, *ws);
  Buffer<float> g(s.device, s.params.size());
  s.net->backward(s.device, {&pbuf, 0}, x, y, dy, {&g, 0}, false, nullptr, *ws);
  const auto once = g.read();
  const auto base = random_vector(s.params.size(), 3);
  g.write(base);
  s.net->backward(s.device, {&pbuf, 0}, x, y, dy, {&g, 0}, true, nullptr, *ws);
  const auto sum = g.read();
  for (std::size_t i = 0; i < sum.size(); ++i)
    ASSERT_NEAR(sum[i], base[i] + once[i], 1e-6 * (1 + std::abs(base[i]) + std::abs(once[i]))) << i;
}

TEST_P(MlpVariant, BitForBitDeterministic) {
  Small s(Json{{"n_neurons", 64}}, 32, 4);
  use_variant(*s.net, GetParam());
  // 2000 samples: several weight-gradient chunks. On the simulator, which checks the kernels' memory accesses and
  // runs them one work-item at a time, 120: a partial last tile.
  const std::uint32_t batch = test::tiny_sizes() ? 120 : 2000;
  Buffer<float> pbuf(s.device, s.params);
  BatchMatrix x(s.device, batch, 32), dy(s.device, batch, 4);
  x.upload_row_major(random_vector(batch * 32, 1));
  dy.upload_row_major(random_vector(batch * 4, 2));
  std::vector<float> out[2], grads[2], dxs[2];
  for (int run = 0; run < 2; ++run) {
    auto ws = s.net->make_workspace(s.device);
    BatchMatrix y(s.device, batch, 4), dx(s.device, batch, 32);
    Buffer<float> g(s.device, s.params.size());
    s.net->forward(s.device, {&pbuf, 0}, x, y, *ws);
    s.net->backward(s.device, {&pbuf, 0}, x, y, dy, {&g, 0}, false, &dx, *ws);
    out[run] = y.download_row_major();
    grads[run] = g.read();
    dxs[run] = dx.download_row_major();
  }
  auto same = [](const std::vector<float>& a, const std::vector<float>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
  };
  EXPECT_TRUE(same(out[0], out[1]));
  EXPECT_TRUE(same(grads[0], grads[1]));
  EXPECT_TRUE(same(dxs[0], dxs[1]));
}

// Central differences of L = sum(c .* f(x)), with a smooth network (hidden activation None, smooth heads),
// evaluated on the device in float (so the device's forward and backward are checked against each other)
// and on the double reference (which checks the reference itself).
TEST_P(MlpVariant, GradientsMatchCentralFiniteDifferences) {
  Small s(Json{{"activation", "None"}});
  use_variant(*s.net, GetParam());
  const std::uint32_t batch = 40, n_in = 5, n_out = 4;
  const auto xh = random_vector(batch * n_in, 11);
  const auto ch = random_vector(batch * n_out, 12);
  Buffer<float> pbuf(s.device, s.params);
  BatchMatrix x(s.device, batch, n_in), y(s.device, batch, n_out), c(s.device, batch, n_out), dx(s.device, batch, n_in);
  x.upload_row_major(xh);
  c.upload_row_major(ch);
  auto ws = s.net->make_workspace(s.device);
  s.net->forward(s.device, {&pbuf, 0}, x, y, *ws);
  Buffer<float> g(s.device, s.params.size());
  s.net->backward(s.device, {&pbuf, 0}, x, y, c, {&g, 0}, false, &dx, *ws);
  const auto grads = g.read();
  const auto dxh = dx.download_row_major();

  auto device_loss = [&](const std::vector<float>& p, const std::vector<float>& xin) {
    pbuf.write(p);
    x.upload_row_major(xin);
    s.net->inference(s.device, {&pbuf, 0}, x, y);
    const auto yh = y.download_row_major();
    double l = 0;
    for (std::size_t i = 0; i < yh.size(); ++i) l += double(ch[i]) * yh[i];
    return l;
  };
  auto ref_loss = [&](const std::vector<float>& p, const std::vector<float>& xin) {
    Reference r(*s.net, p);
    const Mat yv = r.forward(to_mat(xin, batch, n_in));
    return (yv.array() * to_mat(ch, batch, n_out).array()).sum();
  };
  Reference r(*s.net, s.params);
  r.forward(to_mat(xh, batch, n_in));
  std::vector<double> ref_dp;
  Mat ref_dx;
  r.backward(to_mat(xh, batch, n_in), to_mat(ch, batch, n_out), ref_dp, ref_dx);

  const float h_dev = 1e-2f, h_ref = 1e-3f;
  std::mt19937 pick(1);
  for (int i = 0; i < 24; ++i) {  // a sample of parameters (biases included) and inputs
    const std::size_t idx = pick() % s.params.size();
    auto p = s.params;
    p[idx] = s.params[idx] + h_dev;
    const double lp = device_loss(p, xh);
    p[idx] = s.params[idx] - h_dev;
    const double lm = device_loss(p, xh);
    const double fd_dev = (lp - lm) / (2.0 * double(h_dev));
    EXPECT_NEAR(grads[idx], fd_dev, 2e-3 * (1 + std::abs(fd_dev))) << "parameter " << idx << " (device FD)";
    p = s.params;
    p[idx] = s.params[idx] + h_ref;
    const double rp = ref_loss(p, xh);
    p[idx] = s.params[idx] - h_ref;
    const double rm = ref_loss(p, xh);
    const double step = double(s.params[idx] + h_ref) - double(s.params[idx] - h_ref);  // the float step taken
    EXPECT_NEAR(ref_dp[idx], (rp - rm) / step, 1e-6 * (1 + std::abs(ref_dp[idx])))
        << "parameter " << idx << " (reference FD)";
  }
  for (int i = 0; i < 12; ++i) {
    const std::size_t idx = pick() % xh.size();
    auto xp = xh;
    xp[idx] = xh[idx] + h_dev;
    const double lp = device_loss(s.params, xp);
    xp[idx] = xh[idx] - h_dev;
    const double lm = device_loss(s.params, xp);
    const double fd = (lp - lm) / (2.0 * double(h_dev));
    EXPECT_NEAR(dxh[idx], fd, 2e-3 * (1 + std::abs(fd))) << "input " << idx << " (device FD)";
    EXPECT_NEAR(ref_dx(idx / n_in, idx % n_in), dxh[idx], 1e-4 * (1 + std::abs(fd))) << "input " << idx;
  }
}

INSTANTIATE_TEST_SUITE_P(FullyFusedMLP, MlpVariant, ::testing::Values("auto", "simd", "workgroup"),
                         [](const auto& info) { return info.param; });

// A workspace first used with the work-group kernels (which save no ReLU masks) and then, at the same batch,
// with the SIMD kernels (which read them) gives the SIMD kernels' results of a fresh workspace.
TEST(FullyFusedMLP, AWorkspaceFollowsAChangeOfKernelVariant) {
  Small s;
  const std::uint32_t batch = 300;
  Buffer<float> pbuf(s.device, s.params);
  BatchMatrix x(s.device, batch, 5), y(s.device, batch, 4), dy(s.device, batch, 4);
  x.upload_row_major(random_vector(batch * 5, 1));
  dy.upload_row_major(random_vector(batch * 4, 2));
  auto grads = [&](Workspace& ws) {
    Buffer<float> g(s.device, s.params.size());
    s.net->forward(s.device, {&pbuf, 0}, x, y, ws);
    s.net->backward(s.device, {&pbuf, 0}, x, y, dy, {&g, 0}, false, nullptr, ws);
    return g.read();
  };
  auto reused = s.net->make_workspace(s.device);
  s.net->set_workgroup(kWgOdd);
  grads(*reused);
  s.net->set_blocking(Blocking{});
  const auto after_switch = grads(*reused);
  auto fresh = s.net->make_workspace(s.device);
  const auto expected = grads(*fresh);
  ASSERT_EQ(after_switch.size(), expected.size());
  EXPECT_EQ(std::memcmp(after_switch.data(), expected.data(), expected.size() * sizeof(float)), 0);
}

TEST(FullyFusedMLP, InitialisationIsDeterministicAndScaled) {
  Small a, b;
  std::vector<float> p1(a.net->n_params()), p2(a.net->n_params()), p3(a.net->n_params());
  a.net->initialize_params(p1.data(), 42);
  b.net->initialize_params(p2.data(), 42);
  a.net->initialize_params(p3.data(), 43);
  EXPECT_EQ(p1, p2);
  EXPECT_NE(p1, p3);
  // Layer 0 weights within the He bound sqrt(6 / fan_in), biases zero.
  const std::uint32_t n_in = a.net->layer_inputs(0);
  const double bound = std::sqrt(6.0 / n_in);
  for (std::uint32_t j = 0; j < a.net->layer_outputs(0); ++j) {
    for (std::uint32_t k = 0; k < n_in; ++k) EXPECT_LE(std::abs(p1[j * (n_in + 1) + k]), bound);
    EXPECT_EQ(p1[j * (n_in + 1) + n_in], 0.0f);
  }
}

TEST(FullyFusedMLP, ParameterCountAndHyperparameters) {
  auto net =
      make_mlp({{"otype", "FullyFusedMLP"}, {"n_neurons", 32}, {"n_hidden_layers", 2}, {"skip_layers", {1}}}, 3, 2);
  // (3+1)*32 + (32+3+1)*32 + (32+1)*2
  EXPECT_EQ(net->n_params(), 4u * 32 + 36u * 32 + 33u * 2);
  const Json hp = net->hyperparams();
  EXPECT_EQ(hp.at("type"), "FullyFusedMLP");
  EXPECT_EQ(hp.at("n_neurons"), 32);
  auto again = make_mlp(hp, 3, 2);
  EXPECT_EQ(again->hyperparams(), hp);
  EXPECT_EQ(again->n_params(), net->n_params());
}

void expect_config_error(const Json& cfg, const std::string& pointer, const std::string& fragment,
                         std::uint32_t n_in = 3, std::uint32_t n_out = 4) {
  try {
    create_network(cfg, n_in, n_out, "/network");
    ADD_FAILURE() << "no error for " << cfg.dump();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.pointer(), pointer) << e.what();
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(FullyFusedMLP, ConfigErrorsNameTheKey) {
  expect_config_error({{"n_neurons", 48}}, "/network/n_neurons", "256");
  expect_config_error({{"n_neurons", 64}, {"dropout", 0.1}}, "/network/dropout", "unknown key");
  expect_config_error({{"output_heads", {{{"n_dims", 1}}, {{"n_dims", 2}}}}}, "/network/output_heads", "sum to 3");
  expect_config_error({{"n_hidden_layers", 3}, {"skip_layers", {3}}}, "/network/skip_layers", "[1, 2]");
  expect_config_error({{"n_hidden_layers", 3}, {"skip_layers", {0}}}, "/network/skip_layers/0", "[1,");
  expect_config_error({{"output_activation", "Sigmoid"}, {"output_heads", {{{"n_dims", 4}}}}}, "/network/output_heads",
                      "not both");
  expect_config_error({{"output_heads", {{{"n_dims", 4}, {"activation", "Swish"}}}}},
                      "/network/output_heads/0/activation", "Softplus");
  expect_config_error({{"activation", "Sigmoid"}}, "/network/activation", "ReLU");
  expect_config_error({{"n_hidden_layers", 0}}, "/network/n_hidden_layers", "");
}

TEST(FullyFusedMLP, BadCallsAreInvalidArguments) {
  Small s;
  Buffer<float> pbuf(s.device, s.params);
  BatchMatrix x(s.device, 10, 6), y(s.device, 10, 4);
  EXPECT_THROW(s.net->inference(s.device, {&pbuf, 0}, x, y), InvalidArgument);  // 6 columns, network takes 5
  BatchMatrix x5(s.device, 10, 5);
  EXPECT_THROW(s.net->inference(s.device, {&pbuf, 1}, x5, y), InvalidArgument);  // slice past the buffer
  auto ws = s.net->make_workspace(s.device);
  Buffer<float> g(s.device, s.params.size());
  EXPECT_THROW(s.net->backward(s.device, {&pbuf, 0}, x5, y, y, {&g, 0}, false, nullptr, *ws), InvalidArgument);
}

TEST(FullyFusedMLP, BlockingFollowsTheDevice) {
  DeviceInfo avx512, avx2, gpu;
  avx512.type = avx2.type = "cpu";
  gpu.type = "gpu";
  avx512.preferred_vector_width_float = gpu.preferred_vector_width_float = 16;
  avx2.preferred_vector_width_float = 8;
  const auto b512 = FullyFusedMLP::default_blocking(avx512);
  EXPECT_GT(b512.forward_tiles, 1u);
  EXPECT_EQ(b512.dw_vector, 16u);
  EXPECT_GT(b512.fused_train_max_params, 0u);
  EXPECT_TRUE(FullyFusedMLP::default_blocking(avx2) == FullyFusedMLP::Blocking{});
  EXPECT_TRUE(FullyFusedMLP::default_blocking(gpu) == FullyFusedMLP::Blocking{});

  Small s;
  EXPECT_THROW(s.net->set_blocking(FullyFusedMLP::Blocking{0, 4, 4, 8, 4, 3, 16}), InvalidArgument);
  EXPECT_THROW(s.net->set_blocking(FullyFusedMLP::Blocking{1, 4, 4, 12, 4, 3, 16}), InvalidArgument);
  EXPECT_THROW(s.net->set_blocking(FullyFusedMLP::Blocking{1, 4, 4, 8, 4, 3, 10}), InvalidArgument);
  EXPECT_THROW(s.net->set_blocking(FullyFusedMLP::Blocking{1, 4, 4, 1, 4, 5, 16}), InvalidArgument);
  // Reading the saved activations needs them saved transposed: the outer-product form only.
  EXPECT_THROW(s.net->set_blocking(FullyFusedMLP::Blocking{1, 4, 4, 8, 4, 3, 16, 1u << 30, 4, true}), InvalidArgument);
  const FullyFusedMLP::Blocking odd{3, 5, 3, 16, 3, 5, 9, 0, 9};
  EXPECT_THROW(s.net->set_blocking(FullyFusedMLP::Blocking{2, 4, 4, 8, 4, 3, 16, 0, 5}), InvalidArgument);
  s.net->set_blocking(odd);
  EXPECT_TRUE(s.net->blocking(s.device) == odd);
  s.net->set_blocking(std::nullopt);
  EXPECT_TRUE(s.net->blocking(s.device) == FullyFusedMLP::default_blocking(s.device.info()));
}

TEST(FullyFusedMLP, KernelVariantFollowsTheTableConfigAndEnvironment) {
  using Variant = FullyFusedMLP::Variant;
  // The test sets RELIT_MLP_VARIANT itself; a value the suite runs under is put back at the end (ScopedEnv).
  std::optional<test::ScopedEnv> env;
  env.emplace("RELIT_MLP_VARIANT", std::nullopt);
  test::TableDevices d;
  d.cpu.preferred_vector_width_float = 16;  // an AVX-512 CPU
  const DeviceInfo &cpu = d.cpu, &nvidia = d.nvidia, &amd = d.amd, &intel = d.intel, &other = d.other;
  const auto c = FullyFusedMLP::device_default(cpu);
  EXPECT_EQ(c.variant, Variant::Simd);
  EXPECT_TRUE(c.tuned);
  EXPECT_TRUE(c.blocking == FullyFusedMLP::default_blocking(cpu));
  for (const DeviceInfo* gpu : {&nvidia, &amd, &intel, &other}) {
    const auto g = FullyFusedMLP::device_default(*gpu);
    EXPECT_EQ(g.variant, Variant::WorkGroup) << gpu->vendor;
    EXPECT_EQ(g.tuned, gpu == &nvidia) << gpu->vendor;  // only an NVIDIA GPU (an H200) was measured
  }
  EXPECT_NE(FullyFusedMLP::device_default(nvidia).source.find("NVIDIA"), std::string::npos);
  EXPECT_NE(FullyFusedMLP::device_default(amd).source.find("AMD"), std::string::npos);
  EXPECT_EQ(FullyFusedMLP::device_default(amd).workgroup.items, 256u);
  EXPECT_NE(FullyFusedMLP::device_default(intel).source.find("Intel"), std::string::npos);
  EXPECT_NE(FullyFusedMLP::device_default(other).source.find("other"), std::string::npos);
  // AVX-512 CPUs: Intel's weight-gradient work-items own a whole layer's rows, AMD's 24 (mlp_tuning.cpp).
  DeviceInfo amd_cpu = cpu;
  amd_cpu.vendor = "AuthenticAMD";
  EXPECT_EQ(c.source, "table: Intel AVX-512 CPU");
  EXPECT_EQ(c.blocking.dw_region, 256u);
  EXPECT_EQ(FullyFusedMLP::device_default(amd_cpu).source, "table: AVX-512 CPU");
  EXPECT_EQ(FullyFusedMLP::device_default(amd_cpu).blocking.dw_region, 24u);
  EXPECT_EQ(FullyFusedMLP::device_default(amd_cpu).blocking.forward_tiles, c.blocking.forward_tiles);

  // The config's kernel_variant, then RELIT_MLP_VARIANT over it, then set_blocking() / set_workgroup().
  const Device device = test::test_device();
  Small simd(Json{{"kernel_variant", "simd"}}), wg(Json{{"kernel_variant", "workgroup"}}), automatic;
  EXPECT_EQ(simd.net->kernel_choice(device).variant, Variant::Simd);
  EXPECT_EQ(wg.net->kernel_choice(device).variant, Variant::WorkGroup);
  EXPECT_EQ(wg.net->kernel_choice(device).source, "kernel_variant");
  EXPECT_EQ(automatic.net->kernel_choice(device).variant, FullyFusedMLP::default_kernels(device.info()).variant);
  EXPECT_EQ(wg.net->hyperparams().at("kernel_variant"), "workgroup");
  ::setenv("RELIT_MLP_VARIANT", "workgroup", 1);
  EXPECT_EQ(FullyFusedMLP::default_kernels(cpu).variant, Variant::WorkGroup);
  EXPECT_FALSE(FullyFusedMLP::default_kernels(cpu).tuned);
  simd.net->set_blocking(std::nullopt);  // rebuilds: the environment is read when the kernels are built
  EXPECT_EQ(simd.net->kernel_choice(device).variant, Variant::WorkGroup);
  EXPECT_EQ(simd.net->kernel_choice(device).source, "RELIT_MLP_VARIANT");
  simd.net->set_blocking(Blocking{});
  EXPECT_EQ(simd.net->kernel_choice(device).variant, Variant::Simd);
  ::setenv("RELIT_MLP_VARIANT", "SIMD", 1);
  EXPECT_EQ(FullyFusedMLP::default_kernels(nvidia).variant, Variant::Simd);
  ::setenv("RELIT_MLP_VARIANT", "gpu", 1);
  EXPECT_THROW(FullyFusedMLP::default_kernels(cpu), InvalidArgument);
  env.reset();

  EXPECT_THROW(wg.net->set_workgroup(WorkGroupParams{40, 64, 4, 4, 16, 32, 4, 16, 2048}), InvalidArgument);
  EXPECT_THROW(wg.net->set_workgroup(WorkGroupParams{64, 64, 4, 4, 16, 30, 4, 16, 2048}), InvalidArgument);
  EXPECT_THROW(wg.net->set_workgroup(WorkGroupParams{64, 64, 4, 4, 16, 32, 4, 16, 100}), InvalidArgument);
  expect_config_error({{"kernel_variant", "gpu"}}, "/network/kernel_variant", "workgroup");
}

}  // namespace
}  // namespace relit::nn

namespace relit {
namespace {

TEST(NetworkWithInputEncoding, MatricesResizedDownKeepWorking) {
  // A matrix resized to fewer samples keeps its larger padding (no reallocation), as a pass's scratch does for
  // the last, smaller tile of an image; inference and training on it give what fresh matrices give.
  const Device dev = test::test_device();
  auto net = nn::NetworkWithInputEncoding::create(
      {{"encoding", {{"type", "HashGrid"}, {"n_levels", 4}, {"log2_hashmap_size", 10}, {"base_resolution", 4}}},
       {"network", {{"type", "FullyFusedMLP"}, {"n_neurons", 16}, {"n_hidden_layers", 1}}}},
      3, 2);
  std::vector<float> params(net->n_params());
  net->initialize_params(params.data(), 4);
  Buffer<float> p(dev, params), g(dev, params.size());
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  std::vector<float> x(100 * 3);
  for (auto& v : x) v = u(rng);
  nn::BatchMatrix fresh_in(dev, 100, 3), fresh_out(dev, 100, 2), big_in(dev, 1000, 3), big_out(dev, 1000, 2);
  fresh_in.upload_row_major(x);
  big_in.resize(100);
  big_out.resize(100);
  ASSERT_GT(big_in.padded(), fresh_in.padded());
  big_in.upload_row_major(x);
  auto ws = net->make_workspace(dev);
  net->inference(dev, {&p, 0}, fresh_in, fresh_out, *ws);
  const auto want = fresh_out.download_row_major();
  net->inference(dev, {&p, 0}, big_in, big_out, *ws);
  EXPECT_EQ(big_out.download_row_major(), want);
  net->forward(dev, {&p, 0}, big_in, big_out, *ws);
  EXPECT_EQ(big_out.download_row_major(), want);
  nn::BatchMatrix d_out(dev, 1000, 2);
  d_out.resize(100);
  d_out.upload_row_major(std::vector<float>(200, 1.0f));
  net->backward(dev, {&p, 0}, big_in, big_out, d_out, {&g, 0}, false, nullptr, *ws);
  double sum = 0;
  for (float v : g.read()) sum += std::fabs(v);
  EXPECT_GT(sum, 0.0);
}

}  // namespace
}  // namespace relit
