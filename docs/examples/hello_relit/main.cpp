// hello_relit: select a device, run one of relit's kernels, check the result.
#include <relit/relit.hpp>

#include <cmath>
#include <iostream>
#include <vector>

int main() {
  try {
    const relit::Device device = relit::Device::select();  // RELIT_DEVICE, else first GPU, else first device
    const unsigned n = 1000;
    std::vector<float> x(n, 1.0f), y(n);
    for (unsigned i = 0; i < n; ++i) y[i] = float(i);
    relit::Buffer<float> dx(device, x), dy(device, y);
    device.kernel("util.cl", "axpy_f32").args(n, 2.0f, dx, dy).launch(n, 64);  // y = 2x + y
    const std::vector<float> out = dy.read();
    for (unsigned i = 0; i < n; ++i)
      if (std::abs(out[i] - (2.0f + float(i))) > 1e-6f) {
        std::cerr << "wrong result at " << i << ": " << out[i] << '\n';
        return 1;
      }
    std::cout << "relit " << relit::version() << " on " << device.info().description() << ": axpy OK\n";
    return 0;
  } catch (const relit::Error& e) {
    std::cerr << "error: " << e.what() << '\n';
    return 1;
  }
}
