// Benchmarks of nonlinear/deformation_graph.h on a graph of 1,000 nodes (a 10 x 10 x 10 box
// sampled at spacing 1): one Gauss-Newton iteration, the whole solve of a bending edit (warm:
// the graph has solved with these handles before, as while only the targets move; and cold:
// a new graph, paying the Cholesky analysis and a factorisation), applying the solved graph to
// 1M points, and Poisson-disk node sampling.

#include <optional>
#include <vector>

#include <benchmark/benchmark.h>

#include <spacewarp/core/primitives.h>
#include <spacewarp/nonlinear/deformation_graph.h>

namespace {

using namespace spacewarp;

struct GraphSetup {
  std::vector<Vec3> points, handles, targets;
};

// 20,000 points in [0, 10]³; the face x < 1 is held and the face x > 9 is lifted and turned.
const GraphSetup& setup() {
  static const GraphSetup s = [] {
    GraphSetup g;
    g.points = makeRandomPoints(Vec3(0.0), Vec3(10.0), 20'000, 21).positions;
    const double c = 0.9659258262890683, sn = 0.25881904510252074;  // 15 degrees about z
    for (std::size_t i = 0; i < g.points.size(); i += 10) {
      const Vec3& p = g.points[i];
      if (p.x < 1.0) {
        g.handles.push_back(p);
        g.targets.push_back(p);
      } else if (p.x > 9.0) {
        const Vec3 d = p - Vec3(9.5, 5.0, 5.0);
        g.handles.push_back(p);
        g.targets.push_back(Vec3(9.5, 6.0, 5.0) +
                            Vec3(c * d.x - sn * d.y, sn * d.x + c * d.y, d.z));
      }
    }
    return g;
  }();
  return s;
}

DeformationGraph makeGraph() {
  DeformationGraphOptions options;
  options.spacing = 1.0;
  return DeformationGraph(setup().points, options);
}

// One iteration from the rest state, including the per-solve setup (handle weights, the
// assembly of the normal equations). The pattern, its constant part, the analysis and the
// factor kept from the previous solve with the same handles are reused (see solve()).
void BM_GraphOneIteration(benchmark::State& state) {
  DeformationGraph graph = makeGraph();
  DeformationGraphSolveOptions options;
  options.maxIterations = 1;
  for (auto _ : state) {
    graph.reset();
    benchmark::DoNotOptimize(graph.solve(setup().handles, setup().targets, options));
  }
  state.counters["nodes"] = double(graph.nodeCount());
}
BENCHMARK(BM_GraphOneIteration)->Unit(benchmark::kMillisecond)->UseRealTime();

// The whole solve from the rest state to the paper's stopping rule.
void BM_GraphSolve(benchmark::State& state) {
  DeformationGraph graph = makeGraph();
  int iterations = 0;
  for (auto _ : state) {
    graph.reset();
    const DeformationGraphReport report = graph.solve(setup().handles, setup().targets);
    iterations = report.iterations;
    benchmark::DoNotOptimize(report.energies.data());
  }
  state.counters["nodes"] = double(graph.nodeCount());
  state.counters["iterations"] = iterations;
}
BENCHMARK(BM_GraphSolve)->Unit(benchmark::kMillisecond)->UseRealTime();

// The whole solve on a graph that has never solved: pattern, analysis and a factorisation
// included (the graph's construction is not timed).
void BM_GraphSolveCold(benchmark::State& state) {
  int iterations = 0;
  std::optional<DeformationGraph> graph;
  for (auto _ : state) {
    state.PauseTiming();
    graph.reset();  // the previous graph's destruction is not timed either
    graph.emplace(makeGraph());
    state.ResumeTiming();
    const DeformationGraphReport report = graph->solve(setup().handles, setup().targets);
    iterations = report.iterations;
    benchmark::DoNotOptimize(report.energies.data());
  }
  state.counters["iterations"] = iterations;
}
BENCHMARK(BM_GraphSolveCold)->Unit(benchmark::kMillisecond)->UseRealTime();

// Poisson-disk node sampling of the 20,000 points at spacing 1 (graph construction included).
void BM_GraphBuildPoissonDisk(benchmark::State& state) {
  DeformationGraphOptions options;
  options.spacing = 1.0;
  options.sampling = NodeSampling::PoissonDisk;
  std::size_t nodes = 0;
  for (auto _ : state) {
    const DeformationGraph graph(setup().points, options);
    nodes = graph.nodeCount();
  }
  state.counters["nodes"] = double(nodes);
}
BENCHMARK(BM_GraphBuildPoissonDisk)->Unit(benchmark::kMillisecond)->UseRealTime();

// Applying the solved graph to 1M points (applyBatch, TBB).
void BM_GraphApply1M(benchmark::State& state) {
  DeformationGraph graph = makeGraph();
  graph.solve(setup().handles, setup().targets);
  const DeformationGraphWarp warp = graph.warp();
  const std::vector<Vec3> in = makeRandomPoints(Vec3(0.0), Vec3(10.0), 1'000'000, 22).positions;
  std::vector<Vec3> out(in.size());
  for (auto _ : state) {
    warp.applyBatch(in, out);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * int64_t(in.size()));
}
BENCHMARK(BM_GraphApply1M)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
