// The spacewarp benchmark suite: every module's benchmarks in one run and one table, so each
// figure has its baseline measured in the same run.

#include <benchmark/benchmark.h>

#include "bench/bench.h"

#ifdef SPACEWARP_WITH_OPENVDB
/// Prints the warpVolume / OpenVDB GridResampler ratio measured by the volume benchmarks.
void printVolumeSummary();
#endif

void registerSurfaceBenchmarks();  // surface_bench.cpp

#ifdef SPACEWARP_HAVE_HARMONIC
void registerHarmonicBenchmarks();  // harmonic_bench.cpp
#endif

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  registerCoordsBenchmarks();
  registerSurfaceBenchmarks();
#ifdef SPACEWARP_HAVE_HARMONIC
  registerHarmonicBenchmarks();
#endif
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  printCoordsSummary();
#ifdef SPACEWARP_WITH_OPENVDB
  printVolumeSummary();
#endif
  return 0;
}
