// The spacewarp benchmark suite: every module's benchmarks in one run and one table, so each
// figure has its baseline measured in the same run.

#include <benchmark/benchmark.h>

#include "bench/bench.h"

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  registerCoordsBenchmarks();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  printCoordsSummary();
  return 0;
}
