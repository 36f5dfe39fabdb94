// Benchmarks of nonlinear/: moving-least-squares warps. Items are points per second; the copy
// baseline of core_bench.cpp (BM_CopyBaseline) is the floor any batch warp is measured against.

#include <cstdint>
#include <memory>
#include <vector>

#include <benchmark/benchmark.h>

#include <spacewarp/core/binding.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/mls.h>

namespace {

using namespace spacewarp;

constexpr std::size_t kMlsPoints = 1'000'000;

const std::vector<Vec3>& mlsCloud() {
  static const std::vector<Vec3> points =
      makeRandomPoints(Vec3(-1.0), Vec3(1.0), kMlsPoints, 7).positions;
  return points;
}

// n handles in [-1, 1]^3 and targets displaced by up to 0.3 per component.
void mlsHandles(std::size_t n, std::vector<Vec3>& handles, std::vector<Vec3>& targets) {
  handles = makeRandomPoints(Vec3(-1.0), Vec3(1.0), n, 11).positions;
  const std::vector<Vec3> offsets = makeRandomPoints(Vec3(-0.3), Vec3(0.3), n, 13).positions;
  targets.resize(n);
  for (std::size_t i = 0; i < n; ++i) targets[i] = handles[i] + offsets[i];
}

void mlsApplyBatch(benchmark::State& state, MlsMode mode) {
  const auto& in = mlsCloud();
  std::vector<Vec3> out(in.size());
  std::vector<Vec3> handles, targets;
  mlsHandles(static_cast<std::size_t>(state.range(0)), handles, targets);
  MlsOptions options;
  options.mode = mode;
  const MlsWarp warp(handles, targets, options);
  for (auto _ : state) {
    warp.applyBatch(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * in.size()));
}

void BM_MlsRigidApplyBatch(benchmark::State& state) { mlsApplyBatch(state, MlsMode::Rigid); }
BENCHMARK(BM_MlsRigidApplyBatch)->Arg(16)->Arg(64)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_MlsSimilarityApplyBatch(benchmark::State& state) {
  mlsApplyBatch(state, MlsMode::Similarity);
}
BENCHMARK(BM_MlsSimilarityApplyBatch)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_MlsAffineApplyBatch(benchmark::State& state) { mlsApplyBatch(state, MlsMode::Affine); }
BENCHMARK(BM_MlsAffineApplyBatch)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();

// Affine MLS bound once to the point set (MlsAffineCoordinates + Binding, 16 handles): the
// per-frame cost of re-posing the targets is the dense points × handles product.
void BM_MlsAffineBindingDeform(benchmark::State& state) {
  const auto& in = mlsCloud();
  std::vector<Vec3> handles, targets;
  mlsHandles(16, handles, targets);
  const Binding binding(std::make_shared<MlsAffineCoordinates>(handles), in);
  std::vector<Vec3> out(in.size());
  for (auto _ : state) {
    binding.deform(targets, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * in.size()));
}
BENCHMARK(BM_MlsAffineBindingDeform)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
