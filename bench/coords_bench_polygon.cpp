// The cage methods side by side on one convex cage of planar quads (issue 20): weightsBatch of
// the same points by mvc, green, qmvc, qgc and wachspress, end to end (the coordinates made once,
// outside the timing). "pair_time" is seconds per (point × cage face), the same denominator for
// every method, so one column of the table compares them. discrete-harmonic takes triangle faces
// only (a polygon face gives its closed form poles): it runs, with wachspress beside it, on the
// same sphere's vertices cut into triangles (rows ".../triangles"):
//   build/bench/spacewarp_bench --benchmark_filter=BM_PolygonCageWeights

#include <cmath>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/rig/cage_rig.h>

namespace {

using namespace spacewarp;

constexpr int kLongitudes = 20;  // quads per band
constexpr int kBands = 16;  // latitude bands: kBands − 2 of quads, triangle fans at the poles
constexpr std::size_t kPoints = 4096;

// A sphere of radius 1 as a polyhedron of revolution: rings of kLongitudes vertices at the
// latitudes between the poles. Each quad joins two rings at the same two longitudes, so it is a
// planar isosceles trapezoid; every vertex lies on the sphere, so the cage is convex and each
// vertex a corner: 280 quads and 40 triangles, 302 vertices. With `triangles`, each ring turns
// half a longitude further than the one below and the bands are cut into triangles, none
// coplanar with a neighbour (adjacent normals 1.8° apart at least; they are the convex hull's
// faces): 600 triangles, 302 vertices.
std::shared_ptr<const Cage> sphere(bool triangles) {
  PolygonSoup soup;
  const double pi = std::numbers::pi;
  soup.positions.emplace_back(0.0, 0.0, -1.0);
  for (int b = 1; b < kBands; ++b) {
    const double polar = pi - pi * b / kBands;  // from the south pole up
    for (int l = 0; l < kLongitudes; ++l) {
      const double azimuth = 2.0 * pi * (l + (triangles ? 0.5 * b : 0.0)) / kLongitudes;
      soup.positions.emplace_back(std::sin(polar) * std::cos(azimuth),
                                  std::sin(polar) * std::sin(azimuth), std::cos(polar));
    }
  }
  soup.positions.emplace_back(0.0, 0.0, 1.0);
  const auto ring = [](int b, int l) {
    return static_cast<std::uint32_t>(1 + (b - 1) * kLongitudes + (l % kLongitudes));
  };
  const auto north = static_cast<std::uint32_t>(soup.positions.size() - 1);
  for (int l = 0; l < kLongitudes; ++l) {
    soup.addPolygon({0, ring(1, l + 1), ring(1, l)});
    for (int b = 1; b + 1 < kBands; ++b) {
      if (triangles) {
        soup.addPolygon({ring(b, l), ring(b, l + 1), ring(b + 1, l)});
        soup.addPolygon({ring(b, l + 1), ring(b + 1, l + 1), ring(b + 1, l)});
      } else {
        soup.addPolygon({ring(b, l), ring(b, l + 1), ring(b + 1, l + 1), ring(b + 1, l)});
      }
    }
    soup.addPolygon({north, ring(kBands - 1, l), ring(kBands - 1, l + 1)});
  }
  return std::make_shared<const Cage>(soup, triangles ? "triangle sphere" : "quad sphere");
}

void BM_PolygonCageWeights(benchmark::State& state, const std::string& method, bool triangles) {
  static const std::shared_ptr<const Cage> quads = sphere(false), tris = sphere(true);
  const std::shared_ptr<const Cage>& cage = triangles ? tris : quads;
  // Inside either cage: at most 0.55·√3 ≈ 0.95 from the center, every face plane over 0.98 away.
  static const std::vector<Vec3> points =
      makeRandomPoints(Vec3(-0.55), Vec3(0.55), kPoints, 11).positions;
  const auto coordinates = cageCoordinates(method, cage);
  std::vector<double> rows(points.size() * coordinates->columnCount());
  for (auto _ : state) {
    coordinates->weightsBatch(points, rows);
    benchmark::DoNotOptimize(rows.data());
  }
  state.counters["pair_time"] = benchmark::Counter(
      static_cast<double>(points.size() * cage->faceCount()),
      benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * points.size()));
  state.SetLabel(std::to_string(cage->faceCount()) + " faces, " +
                 std::to_string(coordinates->columnCount()) + " columns");
}

[[maybe_unused]] const bool kRegistered = [] {
  const auto add = [](const std::string& name, const char* method, bool triangles) {
    benchmark::RegisterBenchmark(("BM_PolygonCageWeights/" + name).c_str(), BM_PolygonCageWeights,
                                 std::string(method), triangles)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  };
  for (const char* method : {"mvc", "green", "qmvc", "qgc", "wachspress"})
    add(method, method, false);
  for (const char* method : {"wachspress", "discrete-harmonic"})
    add(std::string(method) + "/triangles", method, true);
  return true;
}();

}  // namespace
