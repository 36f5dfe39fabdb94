// Benchmarks of coords. Binding cost of mean-value and Green coordinates is reported per
// (point × cage triangle) pair, on a procedural box cage (always), beside Wachspress and discrete
// harmonic on a convex hull of 200 sphere points (always) and on the Ju et al. armadillo
// (when the shared data is present: the model's 15k vertices and a 1M-point cloud inside its cage,
// the latter both through Binding and through weightsBatch into an allocated matrix). Deforming the
// 1M-point dense binding is measured against a baseline that reads the same weight bytes (a plain
// parallel sum over the matrix) in the same run, both reported as bytes per second, and their
// ratio is printed at the end.
//
// The data directory is $SPACEWARP_SHARED_DATA_DIR, or ../shared/data next to the source tree.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <benchmark/benchmark.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>
#include "bench/bench.h"
#include "tests/coords/convex_test_shapes.h"

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/discrete_harmonic.h>
#include <spacewarp/coords/green.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/coords/quad_green.h>
#include <spacewarp/coords/quad_mean_value.h>
#include <spacewarp/coords/wachspress.h>
#include <spacewarp/core/binding.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>

namespace {

using namespace spacewarp;

constexpr std::size_t kCloudPoints = 1'000'000;

std::filesystem::path armadilloDir() { return bench::sharedDataDir() / "ju2005-armadillo"; }

// Reports seconds per (point × triangle) pair as "pair_time" (shown with SI prefixes, e.g. 7n).
void reportPairs(benchmark::State& state, std::size_t points, std::size_t triangles) {
  state.counters["pair_time"] = benchmark::Counter(
      static_cast<double>(points * triangles),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * points));
}

// Points uniformly distributed inside a closed cage: rejection sampling in its bounding box with
// an even-odd ray cast along +z, accelerated by a grid of triangle lists over (x, y).
std::vector<Vec3> pointsInside(const Cage& cage, std::size_t n, std::uint64_t seed) {
  const BoundingBox box = boundingBox(cage.vertices());
  constexpr int kGrid = 48;
  const Vec3 cell = box.extent() / static_cast<double>(kGrid);
  std::vector<std::vector<std::size_t>> grid(kGrid * kGrid);
  auto cellOf = [&](double v, double lo, double size) {
    return std::clamp(static_cast<int>((v - lo) / size), 0, kGrid - 1);
  };
  for (std::size_t t = 0; t < cage.triangleCount(); ++t) {
    const Triangle tri = cage.triangles()[t];
    const Vec3 a = cage.vertices()[tri.x], b = cage.vertices()[tri.y], c = cage.vertices()[tri.z];
    const Vec3 lo = glm::min(a, glm::min(b, c)), hi = glm::max(a, glm::max(b, c));
    for (int i = cellOf(lo.x, box.min.x, cell.x); i <= cellOf(hi.x, box.min.x, cell.x); ++i)
      for (int j = cellOf(lo.y, box.min.y, cell.y); j <= cellOf(hi.y, box.min.y, cell.y); ++j)
        grid[static_cast<std::size_t>(i * kGrid + j)].push_back(t);
  }
  auto inside = [&](const Vec3& x) {
    const auto& list = grid[static_cast<std::size_t>(cellOf(x.x, box.min.x, cell.x) * kGrid +
                                                     cellOf(x.y, box.min.y, cell.y))];
    int crossings = 0;
    for (std::size_t t : list) {
      const Triangle tri = cage.triangles()[t];
      const Vec3 a = cage.vertices()[tri.x], b = cage.vertices()[tri.y], c = cage.vertices()[tri.z];
      const double d = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
      if (d == 0.0) continue;
      const double u = ((x.x - a.x) * (c.y - a.y) - (x.y - a.y) * (c.x - a.x)) / d;
      const double v = ((b.x - a.x) * (x.y - a.y) - (b.y - a.y) * (x.x - a.x)) / d;
      if (u < 0.0 || v < 0.0 || u + v > 1.0) continue;
      if (a.z + u * (b.z - a.z) + v * (c.z - a.z) > x.z) ++crossings;
    }
    return crossings % 2 == 1;
  };
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ux(box.min.x, box.max.x), uy(box.min.y, box.max.y),
      uz(box.min.z, box.max.z);
  std::vector<Vec3> points;
  points.reserve(n);
  while (points.size() < n) {
    const Vec3 x(ux(rng), uy(rng), uz(rng));
    if (inside(x)) points.push_back(x);
  }
  return points;
}

struct Armadillo {
  std::shared_ptr<const Cage> cage;
  std::shared_ptr<const MeanValueCoordinates> mvc;
  std::shared_ptr<const GreenCoordinates> green;
  std::shared_ptr<const QuadMeanValueCoordinates> qmvc;  // all triangles: MVC's rows
  std::vector<Vec3> model;
  std::vector<Vec3> cloud;
  std::vector<Vec3> posed;
  std::unique_ptr<Binding> cloudBinding;
};

Armadillo& armadillo() {
  static Armadillo data = [] {
    const auto dir = armadilloDir();
    Armadillo a;
    a.cage = std::make_shared<const Cage>(Cage::fromFile(dir / "bounding_mesh.obj"));
    a.mvc = std::make_shared<const MeanValueCoordinates>(a.cage);
    a.green = std::make_shared<const GreenCoordinates>(a.cage);
    a.qmvc = std::make_shared<const QuadMeanValueCoordinates>(a.cage);
    a.model = readSoup(dir / "armadilloman.obj").positions;
    a.cloud = pointsInside(*a.cage, kCloudPoints, 42);
    a.posed = a.cage->posedVerticesFromFile(dir / "deformed_fixed_1.obj");
    return a;
  }();
  return data;
}

const Binding& cloudBinding() {
  Armadillo& a = armadillo();
  if (!a.cloudBinding) a.cloudBinding = std::make_unique<Binding>(a.mvc, a.cloud);
  return *a.cloudBinding;
}

// Procedural: a box cage with 4 x 4 quads per face (98 vertices, 192 triangles), 100k points
// inside it.
void BM_MvcBindBox(benchmark::State& state) {
  const auto cage =
      std::make_shared<const Cage>(makeBoxSurface(Vec3(-1.0), Vec3(1.0), {4, 4, 4}), "box");
  const auto mvc = std::make_shared<const MeanValueCoordinates>(cage);
  const std::vector<Vec3> points = makeRandomPoints(Vec3(-0.99), Vec3(0.99), 100'000, 7).positions;
  for (auto _ : state) {
    Binding binding(mvc, points);
    benchmark::DoNotOptimize(binding.dense().data());
  }
  reportPairs(state, points.size(), cage->triangleCount());
}

// Procedural quad cage: the box [−1, 1]³ with 7 × 7 quads per side (294 quads, 296 vertices),
// its rings turned about z by up to 0.6 rad at the top so that the side quads are non-planar;
// 4k points inside. The same cage is bound by qmvc and qgc on its quads and by MVC and Green on
// its triangulation (588 triangles). "pair_time" is per (point × face the method sees: quad for
// qmvc and qgc, triangle for MVC and Green); "quad_pair_time" is per (point × quad) for all, so
// a quad method's cost per quad compares directly with the cost of the quad's two triangles.
enum class QuadCageMethod { qmvc, qgc, mvc, green };

void BM_BindTwistedQuadBox(benchmark::State& state, QuadCageMethod method) {
  static const auto cage = [] {
    PolygonSoup soup = makeBoxSurface(Vec3(-1.0), Vec3(1.0), {7, 7, 7});
    for (Vec3& p : soup.positions) {
      const double angle = 0.3 * (p.z + 1.0);
      p = Vec3(std::cos(angle) * p.x - std::sin(angle) * p.y,
               std::sin(angle) * p.x + std::cos(angle) * p.y, p.z);
    }
    return std::make_shared<const Cage>(soup, "twisted box");
  }();
  static const std::vector<Vec3> points = pointsInside(*cage, 4'000, 11);
  std::shared_ptr<const Coordinates> coordinates;
  if (method == QuadCageMethod::qmvc)
    coordinates = std::make_shared<QuadMeanValueCoordinates>(cage);
  if (method == QuadCageMethod::qgc) coordinates = std::make_shared<QuadGreenCoordinates>(cage);
  if (method == QuadCageMethod::mvc) coordinates = std::make_shared<MeanValueCoordinates>(cage);
  if (method == QuadCageMethod::green) coordinates = std::make_shared<GreenCoordinates>(cage);
  for (auto _ : state) {
    Binding binding(coordinates, points);
    benchmark::DoNotOptimize(binding.dense().data());
  }
  const bool quads = method == QuadCageMethod::qmvc || method == QuadCageMethod::qgc;
  reportPairs(state, points.size(), quads ? cage->faceCount() : cage->triangleCount());
  state.counters["quad_pair_time"] = benchmark::Counter(
      static_cast<double>(points.size() * cage->faceCount()),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

// qmvc binding the armadillo model (its cage is all triangles, so this is MVC behind qmvc's
// dispatch; CageModeler's QMVC takes 0.21 s for it).
void BM_QmvcBindArmadilloModel(benchmark::State& state) {
  Armadillo& a = armadillo();
  for (auto _ : state) {
    Binding binding(a.qmvc, a.model);
    benchmark::DoNotOptimize(binding.dense().data());
  }
  reportPairs(state, a.model.size(), a.cage->faceCount());
}

// QGC binding the armadillo model: its cage is all triangles, so this is triangle Green through
// QuadGreenCoordinates (CageModeler's QGC: 0.35 s for the same binding).
void BM_QgcBindArmadilloModel(benchmark::State& state) {
  Armadillo& a = armadillo();
  const auto qgc = std::make_shared<const QuadGreenCoordinates>(a.cage);
  for (auto _ : state) {
    Binding binding(qgc, a.model);
    benchmark::DoNotOptimize(binding.dense().data());
  }
  reportPairs(state, a.model.size(), a.cage->faceCount());
}

// Convex: the hull of 200 random points on the unit sphere (396 triangles, every one a face of
// the polyhedron), 20k points inside it, bound by the coordinates C (mean-value for scale, and
// the two convex-polyhedron coordinates), per (point × face).
template <class C>
void BM_BindSphereHull(benchmark::State& state) {
  static const auto cage = std::make_shared<const Cage>(test::randomSphereHull(200, 3), "hull");
  static const std::vector<Vec3> points = pointsInside(*cage, 20'000, 7);
  const auto coordinates = std::make_shared<const C>(cage);
  for (auto _ : state) {
    Binding binding(coordinates, points);
    benchmark::DoNotOptimize(binding.dense().data());
  }
  reportPairs(state, points.size(), cage->faceCount());
}

// Binding the armadillo model or the 1M-point cloud with the coordinates `method` picks.
template <bool green, bool cloud>
void BM_BindArmadillo(benchmark::State& state) {
  Armadillo& a = armadillo();
  const std::shared_ptr<const Coordinates> coordinates =
      green ? std::shared_ptr<const Coordinates>(a.green) : a.mvc;
  const std::vector<Vec3>& points = cloud ? a.cloud : a.model;
  for (auto _ : state) {
    Binding binding(coordinates, points);
    benchmark::DoNotOptimize(binding.dense().data());
  }
  reportPairs(state, points.size(), a.cage->triangleCount());
}

// The same 1M points through weightsBatch into an already allocated matrix: the kernel alone,
// without the Binding's allocation and first touch of its pointCount() × vertexCount() doubles.
void BM_MvcWeightsArmadilloCloud1M(benchmark::State& state) {
  Armadillo& a = armadillo();
  std::vector<double> rows(a.cloud.size() * a.cage->vertexCount(), 0.0);
  for (auto _ : state) {
    a.mvc->weightsBatch(a.cloud, rows);
    benchmark::DoNotOptimize(rows.data());
  }
  reportPairs(state, a.cloud.size(), a.cage->triangleCount());
}

// The kernel alone, on one thread, on the simd::Path state.range(0) forced: the armadillo
// model's weights into an allocated matrix. Every path gives the same bits (simd_paths_test).
template <bool green>
void BM_KernelArmadilloModel(benchmark::State& state) {
  Armadillo& a = armadillo();
  const Coordinates& coordinates =
      green ? static_cast<const Coordinates&>(*a.green) : static_cast<const Coordinates&>(*a.mvc);
  std::vector<double> rows(a.model.size() * coordinates.columnCount(), 0.0);
  detail::simd::forcePath(static_cast<detail::simd::Path>(state.range(0)));
  tbb::task_arena one(1);
  for (auto _ : state) {
    one.execute([&] { coordinates.weightsBatch(a.model, rows); });
    benchmark::DoNotOptimize(rows.data());
  }
  detail::simd::forcePath(std::nullopt);
  reportPairs(state, a.model.size(), a.cage->triangleCount());
}

// Bytes per second of the two memory-bound passes over the 1M-point weight matrix, for the
// ratio printed at the end.
double gDeformRate = 0.0, gReadRate = 0.0;

std::int64_t weightBytes(const Binding& b) {
  return static_cast<std::int64_t>(b.pointCount() * b.columnCount() * sizeof(double));
}

void BM_DeformArmadilloCloud1M(benchmark::State& state) {
  const Binding& binding = cloudBinding();
  const Armadillo& a = armadillo();
  std::vector<Vec3> out(binding.pointCount());
  double seconds = 0.0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    binding.deform(a.posed, out);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  state.SetBytesProcessed(state.iterations() * weightBytes(binding));
  gDeformRate = static_cast<double>(state.iterations() * weightBytes(binding)) / seconds;
}

// Baseline: read the same weight bytes, a plain parallel sum over the matrix.
void BM_ReadBaselineArmadilloCloud1M(benchmark::State& state) {
  const Binding& binding = cloudBinding();
  const double* w = binding.dense().data();
  const std::size_t n = binding.pointCount() * binding.columnCount();
  double seconds = 0.0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    const double sum = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, n, 1 << 16), 0.0,
        [&](const tbb::blocked_range<std::size_t>& r, double s) {
          double acc[4] = {0.0, 0.0, 0.0, 0.0};
          std::size_t i = r.begin();
          for (; i + 4 <= r.end(); i += 4)
            for (int k = 0; k < 4; ++k) acc[k] += w[i + static_cast<std::size_t>(k)];
          for (; i < r.end(); ++i) acc[0] += w[i];
          return s + (acc[0] + acc[1]) + (acc[2] + acc[3]);
        },
        [](double a, double b) { return a + b; });
    benchmark::DoNotOptimize(sum);
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  state.SetBytesProcessed(state.iterations() * weightBytes(binding));
  gReadRate = static_cast<double>(state.iterations() * weightBytes(binding)) / seconds;
}

}  // namespace

void registerCoordsBenchmarks() {
  benchmark::RegisterBenchmark("BM_MvcBindBox", BM_MvcBindBox)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  for (const auto& [name, method] :
       {std::pair{"qmvc", QuadCageMethod::qmvc}, std::pair{"qgc", QuadCageMethod::qgc},
        std::pair{"mvc", QuadCageMethod::mvc}, std::pair{"green", QuadCageMethod::green}}) {
    benchmark::RegisterBenchmark((std::string("BM_BindTwistedQuadBox/") + name).c_str(),
                                 BM_BindTwistedQuadBox, method)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  }
  benchmark::RegisterBenchmark("BM_MvcBindSphereHull", BM_BindSphereHull<MeanValueCoordinates>)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  benchmark::RegisterBenchmark("BM_WachspressBindSphereHull",
                               BM_BindSphereHull<WachspressCoordinates>)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  benchmark::RegisterBenchmark("BM_DiscreteHarmonicBindSphereHull",
                               BM_BindSphereHull<DiscreteHarmonicCoordinates>)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  const auto dir = armadilloDir();
  const bool haveData = std::filesystem::exists(dir / "bounding_mesh.obj") &&
                        std::filesystem::exists(dir / "armadilloman.obj") &&
                        std::filesystem::exists(dir / "deformed_fixed_1.obj");
  if (haveData) {
    benchmark::RegisterBenchmark("BM_MvcBindArmadilloModel", BM_BindArmadillo<false, false>)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark("BM_MvcBindArmadilloCloud1M", BM_BindArmadillo<false, true>)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(3);
    benchmark::RegisterBenchmark("BM_GreenBindArmadilloModel", BM_BindArmadillo<true, false>)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark("BM_QmvcBindArmadilloModel", BM_QmvcBindArmadilloModel)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark("BM_QgcBindArmadilloModel", BM_QgcBindArmadilloModel)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark("BM_GreenBindArmadilloCloud1M", BM_BindArmadillo<true, true>)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(2);
    for (int p = 0; p < detail::simd::kPathCount; ++p) {
      const auto path = static_cast<detail::simd::Path>(p);
      if (!detail::simd::pathSupported(path)) continue;
      const std::string suffix = std::string("/") + detail::simd::pathName(path);
      benchmark::RegisterBenchmark(("BM_MvcKernelArmadilloModel" + suffix).c_str(),
                                   BM_KernelArmadilloModel<false>)
          ->Arg(p)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
      benchmark::RegisterBenchmark(("BM_GreenKernelArmadilloModel" + suffix).c_str(),
                                   BM_KernelArmadilloModel<true>)
          ->Arg(p)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
    benchmark::RegisterBenchmark("BM_MvcWeightsArmadilloCloud1M", BM_MvcWeightsArmadilloCloud1M)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(3);
    benchmark::RegisterBenchmark("BM_DeformArmadilloCloud1M", BM_DeformArmadilloCloud1M)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark("BM_ReadBaselineArmadilloCloud1M", BM_ReadBaselineArmadilloCloud1M)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  } else {
    std::printf("skipping the armadillo benchmarks: %s not found (set SPACEWARP_SHARED_DATA_DIR)\n",
                dir.string().c_str());
  }
}

void printCoordsSummary() {
  if (gDeformRate > 0.0 && gReadRate > 0.0) {
    std::printf("deform %.2f GB/s, read baseline %.2f GB/s, deform/read = %.2f\n",
                gDeformRate * 1e-9, gReadRate * 1e-9, gDeformRate / gReadRate);
  }
}
