// The cage methods side by side on one convex cage of planar quads (issue 20): weightsBatch of
// the same points by mvc, green, qmvc, qgc, wachspress and discrete-harmonic, end to end (the
// coordinates made once, outside the timing). "pair_time" is seconds per (point × cage face),
// the same denominator for every method, so one column of the table compares them:
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
// vertex a corner: 280 quads and 40 triangles, 302 vertices.
std::shared_ptr<const Cage> quadSphere() {
  PolygonSoup soup;
  const double pi = std::numbers::pi;
  soup.positions.emplace_back(0.0, 0.0, -1.0);
  for (int b = 1; b < kBands; ++b) {
    const double polar = pi - pi * b / kBands;  // from the south pole up
    for (int l = 0; l < kLongitudes; ++l) {
      const double azimuth = 2.0 * pi * l / kLongitudes;
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
    for (int b = 1; b + 1 < kBands; ++b)
      soup.addPolygon({ring(b, l), ring(b, l + 1), ring(b + 1, l + 1), ring(b + 1, l)});
    soup.addPolygon({north, ring(kBands - 1, l), ring(kBands - 1, l + 1)});
  }
  return std::make_shared<const Cage>(soup, "quad sphere");
}

void BM_PolygonCageWeights(benchmark::State& state, const std::string& method) {
  static const std::shared_ptr<const Cage> cage = quadSphere();
  // Inside the cage: at most 0.55·√3 ≈ 0.95 from the center, every face plane over 0.98 away.
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
  for (const char* method : {"mvc", "green", "qmvc", "qgc", "wachspress", "discrete-harmonic"})
    benchmark::RegisterBenchmark((std::string("BM_PolygonCageWeights/") + method).c_str(),
                                 BM_PolygonCageWeights, std::string(method))
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
  return true;
}();

}  // namespace
