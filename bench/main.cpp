// The spacewarp benchmark suite: every module's benchmarks in one run and one table, so each
// figure has its baseline measured in the same run.

#include <benchmark/benchmark.h>

#include "bench/bench.h"

#ifdef SPACEWARP_HAVE_HARMONIC
void registerHarmonicBenchmarks();  // harmonic_bench.cpp
#endif

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  registerCoordsBenchmarks();
#ifdef SPACEWARP_HAVE_HARMONIC
  registerHarmonicBenchmarks();
#endif
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  printCoordsSummary();
  return 0;
}
