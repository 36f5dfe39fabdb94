#pragma once
// The benchmark suite is one executable (one table). Shared inputs live here, so the
// benchmarks of different modules measure the same points against the same baseline; files
// whose benchmarks depend on data found at run time register them here instead of with the
// BENCHMARK macro.

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <vector>

#include <benchmark/benchmark.h>

#include <spacewarp/core/primitives.h>

namespace spacewarp::bench {

/// The real models and cages: $SPACEWARP_SHARED_DATA_DIR, or ../shared/data beside the source
/// tree (its path comes from CMake: __FILE__ is relative under ccache's base_dir).
inline std::filesystem::path sharedDataDir() {
  if (const char* env = std::getenv("SPACEWARP_SHARED_DATA_DIR"); env != nullptr && *env != 0)
    return env;
  return std::filesystem::path(SPACEWARP_SOURCE_DIR).parent_path() / "shared" / "data";
}

/// 10M points uniform in [-1, 1]^3 (seed 42), made once: the input of the per-point warp
/// benchmarks and of BM_CopyBaseline.
inline const std::vector<Vec3>& cloud() {
  static const std::vector<Vec3> points =
      makeRandomPoints(Vec3(-1.0), Vec3(1.0), 10'000'000, 42).positions;
  return points;
}

/// Items = points; bytes = the points read and written (2 × 24 bytes each).
inline void reportPoints(benchmark::State& state, std::size_t n) {
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * n * 2 * sizeof(Vec3)));
}

}  // namespace spacewarp::bench

/// Registers the coordinate benchmarks (the armadillo ones only when ../shared/data exists).
void registerCoordsBenchmarks();
/// Prints the deform / read-baseline ratio measured by the coordinate benchmarks, if they ran.
void printCoordsSummary();
