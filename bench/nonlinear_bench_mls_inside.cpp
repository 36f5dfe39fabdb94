// Benchmarks of MLS with distances inside the shape (volume/inside_distance.h): the precompute
// (level set + one fast march per handle) and apply throughput on the 10M-point cloud, with
// plain (Euclidean) MLS on the same handles and points as the baseline in the same run
// (BM_CopyBaseline of core_bench.cpp is the floor). Items are points per second.

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include <benchmark/benchmark.h>

#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/mls.h>
#include <spacewarp/volume/inside_distance.h>
#include "bench/bench.h"

namespace {

using namespace spacewarp;

// Two fingers on a palm spanning [-1, 1]² × [-0.2, 0.2]: cells of 0.4, fingers 4 cells long.
const PolygonSoup& fingers() {
  static const PolygonSoup model = [] {
    std::vector<glm::ivec3> cells;
    for (int x = 0; x <= 4; ++x) cells.emplace_back(x, 0, 0);
    for (int y = 1; y <= 4; ++y) {
      cells.emplace_back(0, y, 0);
      cells.emplace_back(4, y, 0);
    }
    return makeBlocksSurface(cells, Vec3(-1.0, -1.0, -0.2), 0.4);
  }();
  return model;
}

// 16 handles inside the model (8 along each finger-and-palm side), the tip of the left finger
// pulled towards the right one.
void handlesAndTargets(std::vector<Vec3>& handles, std::vector<Vec3>& targets) {
  handles.clear();
  for (int side = 0; side < 2; ++side) {
    const double x = side ? 0.8 : -0.8;
    for (int k = 0; k < 8; ++k) {
      const double z = (k % 2 ? 0.1 : -0.1);
      handles.push_back(Vec3(x + (k % 3 - 1) * 0.05, -0.8 + 0.24 * k, z));
    }
  }
  targets = handles;
  targets[7].x += 0.5;
}

void BM_MlsInsidePrecompute(benchmark::State& state) {
  std::vector<Vec3> handles, targets;
  handlesAndTargets(handles, targets);
  InsideDistanceOptions options;
  options.voxelSize =
      boundingBox(fingers().positions).diagonal() / static_cast<double>(state.range(0));
  std::array<int, 3> grid{};
  for (auto _ : state) {
    const InsideDistances distances(fingers(), handles, options);
    grid = distances.gridSize();
    benchmark::DoNotOptimize(&distances);
  }
  state.counters["voxels"] = static_cast<double>(grid[0]) * grid[1] * grid[2];
  state.counters["handles"] = static_cast<double>(handles.size());
}
// Voxels across the model's diagonal: 128 (the default) and 256.
BENCHMARK(BM_MlsInsidePrecompute)->Arg(128)->Arg(256)->Unit(benchmark::kMillisecond)->UseRealTime();

void mlsApply(benchmark::State& state, bool inside) {
  const auto& in = bench::cloud();
  std::vector<Vec3> out(in.size());
  std::vector<Vec3> handles, targets;
  handlesAndTargets(handles, targets);
  MlsOptions options;
  if (inside) options.distances = std::make_shared<InsideDistances>(fingers(), handles);
  const MlsWarp warp(handles, targets, options);
  for (auto _ : state) {
    warp.applyBatch(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  bench::reportPoints(state, in.size());
}

void BM_MlsInsideApplyBatch(benchmark::State& state) { mlsApply(state, true); }
BENCHMARK(BM_MlsInsideApplyBatch)->Unit(benchmark::kMillisecond)->UseRealTime();

// The baseline: the same rig with Euclidean distances.
void BM_MlsInsideEuclideanBaseline(benchmark::State& state) { mlsApply(state, false); }
BENCHMARK(BM_MlsInsideEuclideanBaseline)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
