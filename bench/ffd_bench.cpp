// Benchmarks of ffd: LatticeWarp::applyBatch on 10M random points inside the box, per basis,
// with the copy-the-same-bytes baseline measured in the same run (see core_bench.cpp).

#include <cstring>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "bench/bench.h"

#include <spacewarp/core/primitives.h>
#include <spacewarp/ffd/lattice_warp.h>

namespace {

using namespace spacewarp;

using spacewarp::bench::cloud;
using spacewarp::bench::reportPoints;

// The baseline, a copy of the same 10M points, is core_bench.cpp's BM_CopyBaseline in the
// same run.

// A lattice on [-1, 1]³ (every point inside) with randomly displaced controls.
LatticeWarp posedLattice(LatticeBasis basis, int resolution) {
  LatticeOptions p;
  p.origin = Vec3(-1.0);
  p.extents = Vec3(2.0);
  p.resolution = {resolution, resolution, resolution};
  p.basis = basis;
  const Lattice lattice(p);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  std::vector<Vec3> posed(lattice.restControlPoints().begin(), lattice.restControlPoints().end());
  for (Vec3& c : posed) {
    const double x = u(rng);
    const double y = u(rng);
    const double z = u(rng);
    c += Vec3(x, y, z);
  }
  return LatticeWarp(lattice, posed);
}

void runLattice(benchmark::State& state, LatticeBasis basis) {
  const auto& in = cloud();
  std::vector<Vec3> out(in.size());
  const LatticeWarp warp = posedLattice(basis, static_cast<int>(state.range(0)));
  for (auto _ : state) {
    warp.applyBatch(in, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  reportPoints(state, in.size());
}

void BM_LatticeTrilinear(benchmark::State& state) { runLattice(state, LatticeBasis::Trilinear); }
BENCHMARK(BM_LatticeTrilinear)->Arg(8)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LatticeBSpline(benchmark::State& state) { runLattice(state, LatticeBasis::BSpline); }
BENCHMARK(BM_LatticeBSpline)->Arg(8)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LatticeBernstein(benchmark::State& state) { runLattice(state, LatticeBasis::Bernstein); }
BENCHMARK(BM_LatticeBernstein)->Arg(4)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
