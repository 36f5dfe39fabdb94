// Benchmarks of core. Each warp benchmark has a baseline measured in the same run: a plain
// copy of the same bytes (what any warp must at least read and write), so figures can be
// quoted as ratios on this shared, noisy machine.

#include <cstring>
#include <numbers>
#include <vector>

#include <benchmark/benchmark.h>

#include "core/primitives.h"
#include "core/twist.h"

namespace {

using namespace spacewarp;

constexpr std::size_t kPoints = 10'000'000;

const std::vector<Vec3>& cloud() {
  static const std::vector<Vec3> points =
      makeRandomPoints(Vec3(-1.0), Vec3(1.0), kPoints, 42).positions;
  return points;
}

void reportPoints(benchmark::State& state, std::size_t n) {
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * n));
  state.SetBytesProcessed(static_cast<int64_t>(state.iterations() * n * 2 * sizeof(Vec3)));
}

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
  TwistParams params;
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
