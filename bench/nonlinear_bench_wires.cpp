// Benchmarks of nonlinear/wires.h: a two-wire rig (one Catmull-Rom, one polyline) over the 10M
// points of bench::cloud(), about half of them within a wire's radius. Items are points per
// second, measured against BM_CopyBaseline of core_bench.cpp in the same run.

#include <cmath>
#include <vector>

#include <benchmark/benchmark.h>

#include <spacewarp/nonlinear/wires.h>
#include "bench.h"

namespace {

using namespace spacewarp;

// Two bent wires crossing the cube [-1, 1]^3, along x and along y.
WiresWarp twoWires(double radius) {
  Wire a, b;
  for (int k = 0; k <= 6; ++k) {
    const double s = -1.2 + 2.4 * k / 6.0;
    a.rest.emplace_back(s, 0.3 * std::sin(2.0 * s), -0.2);
    a.deformed.push_back(a.rest.back() + Vec3(0.0, 0.1, 0.3 * s * s));
    b.rest.emplace_back(0.2 * std::cos(3.0 * s), s, 0.3);
    b.deformed.push_back(b.rest.back() + Vec3(0.2 * s, 0.0, -0.2 * s * s));
  }
  a.curve = WireCurve::CatmullRom;
  a.radius = b.radius = radius;
  a.innerRadius = 0.2 * radius;
  b.scale = 1.3;
  return WiresWarp({a, b}, WiresOptions{});
}

void BM_WiresApplyBatch(benchmark::State& state) {
  const auto& in = spacewarp::bench::cloud();
  std::vector<Vec3> out(in.size());
  const WiresWarp warp = twoWires(0.62);
  for (auto _ : state) {
    warp.applyBatch(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  spacewarp::bench::reportPoints(state, in.size());
  std::size_t moved = 0;
  for (std::size_t i = 0; i < in.size(); ++i) moved += out[i] != in[i];
  state.counters["moved"] = static_cast<double>(moved) / static_cast<double>(in.size());
}
BENCHMARK(BM_WiresApplyBatch)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
