// Surface editing on the Ju et al. armadillo (15k vertices; skipped without the shared data):
// the ARAP factorisation and one local/global iteration, Laplacian editing's back-substitution,
// and cage-subspace ARAP with mean-value coordinates of the armadillo's bounding cage.
//
// The edit is the one the side-by-side libigl measurement uses: the feet (y within 10% of the
// bottom) pinned, the head (within 10% of the top) turned by 30° about z around its centroid
// and carried by 0.15 of the height along x.

#include <cmath>
#include <memory>
#include <optional>

#include <glm/gtc/matrix_transform.hpp>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/surface/arap.h>
#include <spacewarp/surface/cage_arap.h>
#include <spacewarp/surface/laplacian_editing.h>
#include <spacewarp/surface/surface_mesh.h>

#include "bench/bench.h"

namespace spacewarp {
namespace {

struct Edit {
  SurfaceMesh mesh;
  std::vector<std::uint32_t> handles;
  std::vector<Vec3> targets;
  std::shared_ptr<const Coordinates> mvc;
};

const Edit& armadilloEdit() {
  static const Edit edit = [] {
    const auto dir = bench::sharedDataDir() / "ju2005-armadillo";
    Edit e;
    e.mesh = weldSoup(readSoup(dir / "armadilloman.obj"));
    e.mvc = std::make_shared<const MeanValueCoordinates>(
        std::make_shared<const Cage>(Cage::fromFile(dir / "bounding_mesh.obj")));
    const BoundingBox box = boundingBox(e.mesh.positions);
    const double h = box.extent().y;
    Vec3 headCentre(0.0);
    std::size_t headCount = 0;
    for (const Vec3& x : e.mesh.positions)
      if (x.y >= box.max.y - 0.1 * h) {
        headCentre += x;
        ++headCount;
      }
    headCentre /= double(headCount);
    const glm::dmat4 head = glm::translate(glm::dmat4(1.0), headCentre + Vec3(0.15 * h, 0, 0)) *
                            glm::rotate(glm::dmat4(1.0), M_PI / 6.0, Vec3(0, 0, 1)) *
                            glm::translate(glm::dmat4(1.0), -headCentre);
    for (std::uint32_t v = 0; v < e.mesh.vertexCount(); ++v) {
      const Vec3& x = e.mesh.positions[v];
      if (x.y <= box.min.y + 0.1 * h) {
        e.handles.push_back(v);
        e.targets.push_back(x);
      } else if (x.y >= box.max.y - 0.1 * h) {
        e.handles.push_back(v);
        e.targets.push_back(Vec3(head * glm::dvec4(x, 1.0)));
      }
    }
    return e;
  }();
  return edit;
}

constexpr int kIterations = 10;

// Wall time per iteration as a counter (the benchmark's own time covers kIterations of them,
// plus the local step that evaluates the start).
void reportIterations(benchmark::State& state) {
  state.counters["per_iteration"] =
      benchmark::Counter(double(state.iterations()) * kIterations,
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_ArapFactorArmadillo(benchmark::State& state) {
  const Edit& e = armadilloEdit();
  for (auto _ : state) {
    ArapEditor editor(e.mesh.positions, e.mesh.triangles, e.handles);
    benchmark::DoNotOptimize(&editor);
  }
}

void BM_ArapIterationsArmadillo(benchmark::State& state) {
  const Edit& e = armadilloEdit();
  ArapEditor editor(e.mesh.positions, e.mesh.triangles, e.handles,
                    {.maxIterations = kIterations, .relativeTolerance = 0.0});
  LinearEditor laplacian(e.mesh.positions, e.mesh.triangles, e.handles);
  const std::vector<Vec3> start = laplacian.solve(e.targets);
  for (auto _ : state) {
    const ArapResult r = editor.solveFrom(start, e.targets);
    if (r.report.iterations != kIterations) state.SkipWithError("stopped early");
    benchmark::DoNotOptimize(r.positions.data());
  }
  reportIterations(state);
}

void BM_LaplacianResolveArmadillo(benchmark::State& state) {
  const Edit& e = armadilloEdit();
  LinearEditor editor(
      e.mesh.positions, e.mesh.triangles, e.handles,
      {state.range(0) ? LinearEditMethod::BiLaplacian : LinearEditMethod::Laplacian});
  for (auto _ : state) benchmark::DoNotOptimize(editor.solve(e.targets).data());
}

void BM_CageArapSetupArmadillo(benchmark::State& state) {
  const Edit& e = armadilloEdit();
  for (auto _ : state) {
    CageArapEditor editor(e.mesh.positions, e.mesh.triangles, e.mvc, e.handles);
    benchmark::DoNotOptimize(&editor);
  }
}

void BM_CageArapIterationsArmadillo(benchmark::State& state) {
  const Edit& e = armadilloEdit();
  CageArapEditor editor(e.mesh.positions, e.mesh.triangles, e.mvc, e.handles,
                        {.rotationClusters = static_cast<std::size_t>(state.range(0)),
                         .maxIterations = kIterations,
                         .relativeTolerance = 0.0});
  const auto rest = e.mvc->restControlPoints();
  const std::vector<Vec3> start(rest.begin(), rest.end());
  for (auto _ : state) {
    const CageArapResult r = editor.solveFrom(start, e.targets);
    if (r.report.iterations != kIterations) state.SkipWithError("stopped early");
    benchmark::DoNotOptimize(r.positions.data());
  }
  state.counters["clusters"] = double(editor.clusterCount());
  reportIterations(state);
}

}  // namespace
}  // namespace spacewarp

void registerSurfaceBenchmarks() {
  using namespace spacewarp;
  if (!std::filesystem::exists(bench::sharedDataDir() / "ju2005-armadillo" / "armadilloman.obj"))
    return;
  benchmark::RegisterBenchmark("BM_ArapFactorArmadillo", BM_ArapFactorArmadillo)
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("BM_ArapIterationsArmadillo", BM_ArapIterationsArmadillo)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  benchmark::RegisterBenchmark("BM_LaplacianResolveArmadillo", BM_LaplacianResolveArmadillo)
      ->Arg(0)
      ->Arg(1)
      ->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark("BM_CageArapSetupArmadillo", BM_CageArapSetupArmadillo)
      ->Unit(benchmark::kMillisecond)
      ->Iterations(1);
  // 0: the default cluster count; the vertex count: exactly the surface ARAP energy.
  benchmark::RegisterBenchmark("BM_CageArapIterationsArmadillo", BM_CageArapIterationsArmadillo)
      ->Arg(0)
      ->Arg(1 << 30)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
}
