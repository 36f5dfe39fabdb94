// Benchmarks of rbf/: the fit (null-space Cholesky) against a PartialPivLU solve of the full
// saddle-point system, and batch evaluation against a plain scalar loop over the centers with
// the same parallel split, both measured in the same run on this shared, noisy machine.

#include <cmath>
#include <vector>

#include <benchmark/benchmark.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <Eigen/LU>

#include <spacewarp/core/primitives.h>
#include <spacewarp/rbf/rbf_coordinates.h>
#include <spacewarp/rbf/rbf_warp.h>

namespace {

using namespace spacewarp;

struct Handles {
  std::vector<Vec3> centers, targets;
};

Handles handles(std::size_t n) {
  Handles h;
  h.centers = makeRandomPoints(Vec3(-1.0), Vec3(1.0), n, 7).positions;
  const std::vector<Vec3> offsets = makeRandomPoints(Vec3(-0.1), Vec3(0.1), n, 8).positions;
  for (std::size_t i = 0; i < n; ++i) h.targets.push_back(h.centers[i] + offsets[i]);
  return h;
}

const std::vector<Vec3>& cloud() {
  static const std::vector<Vec3> points =
      makeRandomPoints(Vec3(-1.2), Vec3(1.2), 100'000, 42).positions;
  return points;
}

void BM_RbfFitTriharmonic(benchmark::State& state) {
  const Handles h = handles(static_cast<std::size_t>(state.range(0)));
  for (auto _ : state) {
    RbfWarp warp(h.centers, h.targets);
    benchmark::DoNotOptimize(warp.weights().data());
  }
}
BENCHMARK(BM_RbfFitTriharmonic)->Arg(500)->Arg(2000)->Unit(benchmark::kMillisecond)->UseRealTime();

// Baseline: assemble the full (n + 4) system and solve it by PartialPivLU (Eigen).
void BM_RbfFitPartialPivLuBaseline(benchmark::State& state) {
  const Handles h = handles(static_cast<std::size_t>(state.range(0)));
  const Eigen::Index n = static_cast<Eigen::Index>(h.centers.size());
  for (auto _ : state) {
    Eigen::MatrixXd m = Eigen::MatrixXd::Zero(n + 4, n + 4);
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n + 4, 3);
    for (Eigen::Index i = 0; i < n; ++i) {
      const Vec3& c = h.centers[static_cast<std::size_t>(i)];
      for (Eigen::Index j = 0; j < n; ++j) {
        const double r = glm::length(c - h.centers[static_cast<std::size_t>(j)]);
        m(i, j) = r * r * r;
      }
      const double p[4] = {1.0, c.x, c.y, c.z};
      for (int k = 0; k < 4; ++k) m(i, n + k) = m(n + k, i) = p[k];
      for (int k = 0; k < 3; ++k) rhs(i, k) = h.targets[static_cast<std::size_t>(i)][k] - c[k];
    }
    const Eigen::MatrixXd x = m.partialPivLu().solve(rhs);
    benchmark::DoNotOptimize(x.data());
  }
}
BENCHMARK(BM_RbfFitPartialPivLuBaseline)
    ->Arg(500)
    ->Arg(2000)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void reportPairs(benchmark::State& state, std::size_t points, std::size_t centers) {
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * points * centers));
}

void BM_RbfApplyBatchTriharmonic(benchmark::State& state) {
  const Handles h = handles(static_cast<std::size_t>(state.range(0)));
  const RbfWarp warp(h.centers, h.targets);
  const auto& in = cloud();
  std::vector<Vec3> out(in.size());
  for (auto _ : state) {
    warp.applyBatch(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  reportPairs(state, in.size(), warp.centers().size());
}
BENCHMARK(BM_RbfApplyBatchTriharmonic)->Arg(2000)->Unit(benchmark::kMillisecond)->UseRealTime();

// Every kernel (range(0) = RbfKernel), 2,000 centers, 100k points.
void BM_RbfApplyBatchKernel(benchmark::State& state) {
  const Handles h = handles(2000);
  RbfOptions options;
  options.kernel = static_cast<RbfKernel>(state.range(0));
  options.scale = 0.3;
  options.radius = 0.8;
  const RbfWarp warp(h.centers, h.targets, options);
  state.SetLabel(rbfKernelName(options.kernel));
  const auto& in = cloud();
  std::vector<Vec3> out(in.size());
  for (auto _ : state) {
    warp.applyBatch(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  reportPairs(state, in.size(), warp.centers().size());
}
BENCHMARK(BM_RbfApplyBatchKernel)->DenseRange(0, 5)->Unit(benchmark::kMillisecond)->UseRealTime();

// Baseline: the same sum as a plain scalar loop (array of structures, std::sqrt), with the
// same TBB split over points.
void BM_RbfScalarLoopBaseline(benchmark::State& state) {
  const Handles h = handles(static_cast<std::size_t>(state.range(0)));
  const RbfWarp warp(h.centers, h.targets);
  const auto centers = warp.centers();
  const auto weights = warp.weights();
  const auto& in = cloud();
  std::vector<Vec3> out(in.size());
  for (auto _ : state) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, in.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i != r.end(); ++i) {
                          Vec3 d = warp.linearPart() * in[i] + warp.translation();
                          for (std::size_t j = 0; j < centers.size(); ++j) {
                            const double rr = glm::length(centers[j] - in[i]);
                            d += (rr * rr * rr) * weights[j];
                          }
                          out[i] = in[i] + d;
                        }
                      });
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  reportPairs(state, in.size(), centers.size());
}
BENCHMARK(BM_RbfScalarLoopBaseline)->Arg(2000)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_RbfCoordinatesBuild(benchmark::State& state) {
  const Handles h = handles(static_cast<std::size_t>(state.range(0)));
  for (auto _ : state) {
    RbfCoordinates coords(h.centers);
    benchmark::DoNotOptimize(&coords);
  }
}
BENCHMARK(BM_RbfCoordinatesBuild)
    ->Arg(500)
    ->Arg(2000)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
