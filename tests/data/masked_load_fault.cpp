// The image fit's loop before commit 4abf79d, which GCC 12 miscompiles with AVX masked loads (decisions D55):
// a conditional load from a group of three channels. scripts/audit_mask_loads.py --control compiles and runs it;
// exit status 1 when the answer is wrong.
#include <cmath>
#include <cstdio>
#include <vector>

struct Rgb {
  double r, g, b;
};

__attribute__((noinline)) double mean_relative_error(const std::vector<Rgb> &model, const std::vector<Rgb> &maps) {
  double sum = 0.0;
  for (size_t k = 0; k < maps.size(); k++) {
    const double x[3] = {model[k].r, model[k].g, model[k].b}, t[3] = {maps[k].r, maps[k].g, maps[k].b};
    for (int c = 0; c < 3; c++) {
      sum += t[c] > 0.0 ? std::abs(x[c] / t[c] - 1.0) : 0.0;
    }
  }
  return sum / double(3 * maps.size());
}

int main() {
  // Black channels at different places of the group: each counts 0, whichever vector holds it.
  std::vector<Rgb> maps;
  for (int k = 0; k < 64; k++) {
    maps.push_back({k % 3 == 0 ? 0.0 : 1.0 + k, k % 5 == 1 ? 0.0 : 0.5, k % 7 == 2 ? 0.0 : 0.25 * k + 1.0});
  }
  const double e = mean_relative_error(maps, maps);
  std::printf("error of the maps against themselves %g (right: 0)\n", e);
  return e == 0.0 ? 0 : 1;
}
