// Shepard (inverse-distance weighting) and Kelvinlet brushes on the shared 10M-point cloud
// (bench.h), against BM_CopyBaseline of the same run.

#include <memory>
#include <vector>

#include <benchmark/benchmark.h>

#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/kelvinlet.h>
#include <spacewarp/nonlinear/shepard.h>

#include "bench.h"

namespace {

using namespace spacewarp;

// Shepard warp of n handles in [-1.2, 1.2]^3 (so that a support radius reaches every point of
// the cloud's corners too) displaced by up to 0.3 per component; range(1) is the support radius
// in hundredths (0: global weights).
void BM_ShepardApplyBatch(benchmark::State& state) {
  const auto& in = bench::cloud();
  std::vector<Vec3> out(in.size());
  const auto n = static_cast<std::size_t>(state.range(0));
  const std::vector<Vec3> handles = makeRandomPoints(Vec3(-1.2), Vec3(1.2), n, 11).positions;
  const std::vector<Vec3> offsets = makeRandomPoints(Vec3(-0.3), Vec3(0.3), n, 13).positions;
  std::vector<Vec3> targets(n);
  for (std::size_t i = 0; i < n; ++i) targets[i] = handles[i] + offsets[i];
  ShepardOptions options;
  if (state.range(1) > 0) options.radius = static_cast<double>(state.range(1)) / 100.0;
  const ShepardWarp warp(handles, targets, options);
  for (auto _ : state) {
    warp.applyBatch(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  bench::reportPoints(state, in.size());
}
// 16 handles, global; 1024 handles with a radius of 0.6 (about 67 within reach of a point).
BENCHMARK(BM_ShepardApplyBatch)
    ->Args({16, 0})
    ->Args({1024, 60})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_KelvinletApplyBatch(benchmark::State& state) {
  const auto& in = bench::cloud();
  std::vector<Vec3> out(in.size());
  KelvinletOptions o;
  o.brush = static_cast<KelvinletBrush>(state.range(0));
  o.radius = 0.5;
  o.displacement = Vec3(0.3, 0.1, 0.0);
  o.axis = Vec3(0.0, 0.0, 1.0);
  o.angle = 0.8;
  o.factor = 1.3;
  o.matrix = Mat3(0.0);
  o.matrix[0][0] = 0.2;
  o.matrix[1][1] = -0.2;
  const KelvinletWarp warp(o);
  state.SetLabel(kelvinletBrushName(o.brush));
  for (auto _ : state) {
    warp.applyBatch(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  bench::reportPoints(state, in.size());
}
BENCHMARK(BM_KelvinletApplyBatch)
    ->Arg(static_cast<int>(KelvinletBrush::Grab))
    ->Arg(static_cast<int>(KelvinletBrush::Twist))
    ->Arg(static_cast<int>(KelvinletBrush::Scale))
    ->Arg(static_cast<int>(KelvinletBrush::Pinch))
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
