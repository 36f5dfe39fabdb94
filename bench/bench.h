#pragma once
// The benchmark suite is one executable (one table). Files whose benchmarks depend on data
// found at run time register them here instead of with the BENCHMARK macro.

/// Registers the coordinate benchmarks (the armadillo ones only when ../shared/data exists).
void registerCoordsBenchmarks();
/// Prints the deform / read-baseline ratio measured by the coordinate benchmarks, if they ran.
void printCoordsSummary();
