// Benchmarks of harmonic coordinates on the Ju et al. armadillo cage (110 vertices) at the default
// resolution (about 200k tets): the whole solve with each phase (tetrahedralise, factorise =
// assembly + LDLᵀ, solve = all 110 right-hand sides + the non-negativity projection) reported as
// counters in seconds, TetGen alone, point location, full weight rows and a deform through the
// Warp view, and the process's peak resident memory (getrusage ru_maxrss) after the solve.
// Skipped when the shared data is absent ($SPACEWARP_SHARED_DATA_DIR, or ../shared/data next to
// the source tree).

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/harmonic.h>
#include <spacewarp/coords/harmonic_warp.h>
#include <spacewarp/coords/tet_mesh.h>
#include <spacewarp/core/coordinate_warp.h>
#include "bench/bench.h"

namespace {

using namespace spacewarp;
using Clock = std::chrono::steady_clock;

constexpr std::size_t kPoints = 1'000'000;      // location and deform
constexpr std::size_t kWeightPoints = 200'000;  // full rows: 110 doubles each

std::filesystem::path cageFile() {
  return bench::sharedDataDir() / "ju2005-armadillo" / "bounding_mesh.obj";
}

double peakMegabytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // ru_maxrss is in kilobytes on Linux
}

struct Armadillo {
  std::shared_ptr<const Cage> cage;
  std::shared_ptr<const HarmonicCoordinates> harmonic;
  std::vector<Vec3> inside;  // kPoints points inside the cage
};

Armadillo& armadillo() {
  static Armadillo a = [] {
    Armadillo r;
    r.cage = std::make_shared<const Cage>(Cage::fromFile(cageFile()));
    r.harmonic = std::make_shared<const HarmonicCoordinates>(r.cage);
    Vec3 lo(1e300), hi(-1e300);
    for (const Vec3& p : r.cage->vertices()) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    std::mt19937_64 rng(42);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    while (r.inside.size() < kPoints) {
      const Vec3 x = lo + (hi - lo) * Vec3(unit(rng), unit(rng), unit(rng));
      if (r.harmonic->locate(x).found) r.inside.push_back(x);
    }
    return r;
  }();
  return a;
}

// The whole solve, with the time of every phase from the progress callback.
void BM_HarmonicSolveArmadillo(benchmark::State& state) {
  const auto cage = std::make_shared<const Cage>(Cage::fromFile(cageFile()));
  std::map<std::string, double> begin, end, total;
  std::size_t tets = 0, vertices = 0;
  for (auto _ : state) {
    const Clock::time_point t0 = Clock::now();
    const ProgressCallback progress = [&](std::string_view stage, double fraction) {
      const double t = std::chrono::duration<double>(Clock::now() - t0).count();
      const std::string name(stage);
      if (fraction == 0.0 && !begin.count(name)) begin[name] = t;
      if (fraction == 1.0) end[name] = t;
      return true;
    };
    begin.clear();
    end.clear();
    const HarmonicCoordinates h(cage, HarmonicOptions{}, progress);
    tets = h.mesh().tets.size();
    vertices = h.mesh().vertices.size();
    for (const auto& [stage, t] : end) total[stage] += t - begin[stage];
  }
  const auto n = static_cast<double>(state.iterations());
  for (const auto& [stage, t] : total) state.counters[stage + "_s"] = t / n;
  state.counters["tets"] = static_cast<double>(tets);
  state.counters["mesh_vertices"] = static_cast<double>(vertices);
  state.counters["peak_MB"] = peakMegabytes();
}

void BM_HarmonicTetGenArmadillo(benchmark::State& state) {
  const Cage cage = Cage::fromFile(cageFile());
  const double bound = HarmonicCoordinates::tetVolumeBound(cage, HarmonicOptions{});
  std::size_t tets = 0;
  for (auto _ : state) tets = tetrahedraliseCage(cage, {2.0, bound}).tets.size();
  state.counters["tets"] = static_cast<double>(tets);
}

void BM_HarmonicLocateArmadillo(benchmark::State& state) {
  const Armadillo& a = armadillo();
  std::vector<TetLocator::Hit> out(a.inside.size());
  for (auto _ : state) {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, a.inside.size(), 4096),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i != r.end(); ++i)
                          out[i] = a.harmonic->locate(a.inside[i]);
                      });
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * a.inside.size()));
}

void BM_HarmonicWeightsArmadillo(benchmark::State& state) {
  const Armadillo& a = armadillo();
  const std::span<const Vec3> points(a.inside.data(), kWeightPoints);
  std::vector<double> rows(points.size() * a.cage->vertexCount());
  for (auto _ : state) {
    a.harmonic->weightsBatch(points, rows);
    benchmark::DoNotOptimize(rows.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * points.size()));
  state.counters["peak_MB"] = peakMegabytes();
}

std::vector<Vec3> posedArmadillo(const Cage& cage) {
  std::vector<Vec3> posed(cage.vertices().begin(), cage.vertices().end());
  for (std::size_t i = 0; i < posed.size(); ++i) {
    const double t = static_cast<double>(i);
    posed[i] += 0.01 * cage.diagonal() * Vec3(std::sin(t), std::cos(t), std::sin(2.0 * t));
  }
  return posed;
}

// The generic Warp view (weight rows of 110 columns per point).
void BM_HarmonicCoordinateWarpArmadillo(benchmark::State& state) {
  const Armadillo& a = armadillo();
  const CoordinateWarp warp(a.harmonic, posedArmadillo(*a.cage));
  const std::span<const Vec3> points(a.inside.data(), kWeightPoints);
  std::vector<Vec3> out(points.size());
  for (auto _ : state) {
    warp.applyBatch(points, out);
    benchmark::DoNotOptimize(out.data());
  }
  spacewarp::bench::reportPoints(state, points.size());
}

// HarmonicWarp: location plus a 4-term mix of per-vertex displacements.
void BM_HarmonicDeformArmadillo(benchmark::State& state) {
  const Armadillo& a = armadillo();
  const HarmonicWarp warp(a.harmonic, posedArmadillo(*a.cage));
  std::vector<Vec3> out(a.inside.size());
  for (auto _ : state) {
    warp.applyBatch(a.inside, out);
    benchmark::DoNotOptimize(out.data());
  }
  spacewarp::bench::reportPoints(state, a.inside.size());
}

}  // namespace

void registerHarmonicBenchmarks() {
  if (!std::filesystem::exists(cageFile())) {
    std::printf("skipping the harmonic benchmarks: %s not found (set SPACEWARP_SHARED_DATA_DIR)\n",
                cageFile().string().c_str());
    return;
  }
  benchmark::RegisterBenchmark("BM_HarmonicSolveArmadillo", BM_HarmonicSolveArmadillo)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime()
      ->Iterations(3);
  benchmark::RegisterBenchmark("BM_HarmonicTetGenArmadillo", BM_HarmonicTetGenArmadillo)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime()
      ->Iterations(2);
  benchmark::RegisterBenchmark("BM_HarmonicLocateArmadillo1M", BM_HarmonicLocateArmadillo)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  benchmark::RegisterBenchmark("BM_HarmonicWeightsArmadillo200k", BM_HarmonicWeightsArmadillo)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  benchmark::RegisterBenchmark("BM_HarmonicCoordinateWarpArmadillo200k",
                               BM_HarmonicCoordinateWarpArmadillo)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  benchmark::RegisterBenchmark("BM_HarmonicWarpArmadillo1M", BM_HarmonicDeformArmadillo)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
}
