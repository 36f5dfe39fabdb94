// Benchmarks of core. Each warp benchmark has a baseline measured in the same run: a plain
// copy of the same bytes (what any warp must at least read and write), so figures can be
// quoted as ratios on this shared, noisy machine.

#include <cstring>
#include <numbers>
#include <vector>

#include <benchmark/benchmark.h>

#include "bench/bench.h"

#include <spacewarp/core/primitives.h>
#include <spacewarp/core/twist.h>

namespace {

using namespace spacewarp;

using spacewarp::bench::cloud;
using spacewarp::bench::reportPoints;

// Baseline: copying the input to the output, the same bytes a batch warp reads and writes.
void BM_CopyBaseline(benchmark::State& state) {
  const auto& in = cloud();
  std::vector<Vec3> out(in.size());
  for (auto _ : state) {
    std::memcpy(out.data(), in.data(), in.size() * sizeof(Vec3));
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  reportPoints(state, in.size());
}
BENCHMARK(BM_CopyBaseline)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_TwistApplyBatch(benchmark::State& state) {
  const auto& in = cloud();
  std::vector<Vec3> out(in.size());
  TwistOptions params;
  params.axis = Vec3(0.3, 0.4, 1.0);
  params.rate = std::numbers::pi / 2;
  const TwistWarp twist(params);
  for (auto _ : state) {
    twist.applyBatch(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  reportPoints(state, in.size());
}
BENCHMARK(BM_TwistApplyBatch)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
