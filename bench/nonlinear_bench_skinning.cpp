// Benchmarks of nonlinear/skinning.h: the binding's deform of the 10M-point cloud with 4 of 16
// bones per point (LBS and DQS: the per-frame path), the SkinningWarp of 1M of those points
// (nearest-vertex weights of a 100k-vertex model, and weights from MLS-affine coordinates of
// the 16 handles on 100k points), against BM_CopyBaseline (core_bench.cpp) in the same run.

#include <cmath>
#include <memory>
#include <random>
#include <span>
#include <vector>

#include <benchmark/benchmark.h>
#include <glm/gtc/matrix_transform.hpp>

#include <spacewarp/nonlinear/mls.h>
#include <spacewarp/nonlinear/skinning.h>

#include "bench/bench.h"

namespace {

using namespace spacewarp;
using spacewarp::bench::cloud;
using spacewarp::bench::reportPoints;

constexpr std::size_t kBones = 16;

// 16 handles on a 4 × 4 grid in the plane z = 0.
std::vector<Vec3> handles() {
  std::vector<Vec3> h;
  for (std::size_t i = 0; i < kBones; ++i)
    h.emplace_back(-0.75 + 0.5 * double(i % 4), -0.75 + 0.5 * double(i / 4), 0.1 * double(i % 3));
  return h;
}

// Rigid bones: each turns by up to 40° about its own axis through its handle, and moves.
std::vector<Mat4> bones() {
  std::vector<Mat4> out;
  const std::vector<Vec3> h = handles();
  for (std::size_t i = 0; i < kBones; ++i) {
    const double angle = 0.7 * std::sin(double(i) + 1.0);
    const Vec3 axis = glm::normalize(Vec3(std::cos(double(i)), std::sin(2.0 * double(i)), 1.0));
    const Mat3 r(glm::rotate(Mat4(1.0), angle, axis));
    Mat4 m(r);
    m[3] = glm::dvec4(h[i] - r * h[i] + Vec3(0.05 * double(i % 5), 0.0, 0.02), 1.0);
    out.push_back(m);
  }
  return out;
}

// 4 influences per point, from the 4 handles nearest in the grid's cell, with inverse-distance
// weights: the sparsity pattern a real rig has (neighbouring points share bones).
SkinningWeights weightsOf(std::span<const Vec3> points) {
  SkinningWeights w;
  w.pointCount = points.size();
  w.influences = 4;
  w.bones.resize(points.size() * 4);
  w.weights.resize(points.size() * 4);
  const std::vector<Vec3> h = handles();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3& p = points[i];
    const auto cell = [](double v) {
      return std::size_t(std::min(2.0, std::max(0.0, std::floor((v + 0.75) / 0.5))));
    };
    const std::size_t cx = cell(p.x), cy = cell(p.y);
    const std::size_t b[4] = {cy * 4 + cx, cy * 4 + cx + 1, (cy + 1) * 4 + cx,
                              (cy + 1) * 4 + cx + 1};
    double sum = 0.0, raw[4];
    for (int j = 0; j < 4; ++j) sum += raw[j] = 1.0 / (0.01 + glm::length(p - h[b[j]]));
    for (int j = 0; j < 4; ++j) {
      w.bones[i * 4 + std::size_t(j)] = std::uint32_t(b[j]);
      w.weights[i * 4 + std::size_t(j)] = raw[j] / sum;
    }
  }
  return w;
}

const SkinningBinding& binding() {
  static const SkinningBinding b(cloud(), weightsOf(cloud()), kBones);
  return b;
}

void bindingDeform(benchmark::State& state, SkinningMode mode) {
  const SkinningBinding& b = binding();
  const std::vector<Mat4> posed = bones();
  std::vector<Vec3> out(b.pointCount());
  for (auto _ : state) {
    b.deform(posed, mode, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  reportPoints(state, out.size());
  state.counters["points/s"] =
      benchmark::Counter(double(out.size()), benchmark::Counter::kIsIterationInvariantRate);
}

void BM_SkinningBindingDeformLbs(benchmark::State& state) {
  bindingDeform(state, SkinningMode::Linear);
}
BENCHMARK(BM_SkinningBindingDeformLbs)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SkinningBindingDeformDqs(benchmark::State& state) {
  bindingDeform(state, SkinningMode::DualQuaternion);
}
BENCHMARK(BM_SkinningBindingDeformDqs)->Unit(benchmark::kMillisecond)->UseRealTime();

// Warps `in` once per iteration and reports points per second.
void applyBatchLoop(benchmark::State& state, const Warp& warp, std::span<const Vec3> in) {
  std::vector<Vec3> out(in.size());
  for (auto _ : state) {
    warp.applyBatch(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  reportPoints(state, out.size());
  state.counters["points/s"] =
      benchmark::Counter(double(out.size()), benchmark::Counter::kIsIterationInvariantRate);
}

// The warp of space: 1M query points, weights of the nearest of 100k weighted model vertices.
void BM_SkinningWarpNearestVertex(benchmark::State& state) {
  const auto mode = static_cast<SkinningMode>(state.range(0));
  const std::span<const Vec3> model(cloud().data(), 100'000);
  const std::span<const Vec3> in(cloud().data() + 100'000, 1'000'000);
  const SkinningWarp warp(bones(), {model.begin(), model.end()}, weightsOf(model), mode);
  applyBatchLoop(state, warp, in);
}
BENCHMARK(BM_SkinningWarpNearestVertex)
    ->Arg(int(SkinningMode::Linear))
    ->Arg(int(SkinningMode::DualQuaternion))
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The warp of space with weights from MLS-affine coordinates of the 16 handles (4 kept), on
// 100k points: dominated by the coordinates.
void BM_SkinningWarpCoordinates(benchmark::State& state) {
  const auto mode = static_cast<SkinningMode>(state.range(0));
  const std::span<const Vec3> in(cloud().data(), 100'000);
  const SkinningWarp warp(bones(), std::make_shared<MlsAffineCoordinates>(handles()), {mode, 4});
  applyBatchLoop(state, warp, in);
}
BENCHMARK(BM_SkinningWarpCoordinates)
    ->Arg(int(SkinningMode::Linear))
    ->Arg(int(SkinningMode::DualQuaternion))
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
