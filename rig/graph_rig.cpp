#include <spacewarp/rig/detail/graph_rig.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>
#include <spacewarp/nonlinear/deformation_graph.h>

namespace spacewarp::detail {

namespace {

constexpr double kMaxGridNodes = 2.0e6;

// Peak memory of building and solving a graph of n nodes: the sparse Cholesky factor of its
// 12 n unknowns fills as n^(4/3) on a grid (the separators of a 3D mesh). Measured with k = 4
// on grid rigs (peak RSS: 730 MB for 8,000 nodes, over 9 GB for 64,000), about
// 4.6 kB · n^(4/3); rounded up.
constexpr double kBytesPerNodePower = 5000.0;

// Refuses a graph too large for the memory available, before anything is allocated (the rig
// builder puts the rig's name in front). More neighbours than 4 fill the factor more.
void checkGraphMemory(double nodes, int k, const std::string& key) {
  detail::checkMemory(kBytesPerNodePower * std::pow(nodes, 4.0 / 3.0) * std::max(1.0, k / 4.0),
                      "'" + key + "' (" + std::to_string(std::llround(nodes)) + " graph nodes)");
}

// Grid nodes of spacing s over the handles' bounding box padded by 2 s, x fastest.
std::vector<Vec3> gridNodes(RigReader& r, const std::vector<Vec3>& handles, double s, int k) {
  const BoundingBox box = boundingBox(handles);
  const Vec3 lo = box.min - Vec3(2.0 * s);
  const Vec3 extent = box.extent() + Vec3(4.0 * s);
  double counts[3];
  for (int a = 0; a < 3; ++a) counts[a] = std::ceil(extent[a] / s - 1e-9) + 1.0;
  if (!(counts[0] * counts[1] * counts[2] <= kMaxGridNodes)) {
    r.fail("spacing", "gives more than 2,000,000 grid nodes over the handles' bounding box");
  }
  checkGraphMemory(counts[0] * counts[1] * counts[2], k, "spacing");
  const int nx = int(counts[0]), ny = int(counts[1]), nz = int(counts[2]);
  std::vector<Vec3> nodes;
  nodes.reserve(std::size_t(nx) * std::size_t(ny) * std::size_t(nz));
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) nodes.push_back(lo + s * Vec3(i, j, k));
  return nodes;
}

}  // namespace

Rig graphRig(RigReader& r) {
  const std::vector<Vec3> handles = r.points("handles");
  const std::vector<Vec3> targets = r.points("targets");
  if (targets.size() != handles.size()) {
    r.fail("targets", "must have as many points as 'handles' (" + std::to_string(handles.size()) +
                          "), not " + std::to_string(targets.size()));
  }
  DeformationGraphOptions options;
  const double k = r.number("k", options.k);
  if (!(k >= 1.0) || k != std::floor(k) || k > 64.0) r.fail("k", "must be an integer in [1, 64]");
  options.k = int(k);
  std::vector<Vec3> nodes;
  if (r.has("nodes")) {
    if (r.has("spacing"))
      r.fail("spacing", "is not read when 'nodes' is given: remove one of them");
    nodes = r.points("nodes");
    checkGraphMemory(double(nodes.size()), options.k, "nodes");
  } else {
    options.spacing = r.number("spacing");
    // Beyond 1e150 the grid's squared distances overflow (DeformationGraph refuses its nodes).
    if (!(options.spacing > 0.0 && options.spacing <= 1e150))
      r.fail("spacing", "must be > 0 and at most 1e150");
    nodes = gridNodes(r, handles, options.spacing, options.k);
  }
  if (options.k >= int(std::min<std::size_t>(nodes.size(), 65))) {
    r.fail("k", "must be less than the number of nodes (" + std::to_string(nodes.size()) + ")");
  }
  DeformationGraphSolveOptions solve;
  solve.rotationWeight = r.number("rotationWeight", solve.rotationWeight);
  solve.regularizationWeight = r.number("regularizationWeight", solve.regularizationWeight);
  solve.constraintWeight = r.number("constraintWeight", solve.constraintWeight);
  for (const char* key : {"rotationWeight", "regularizationWeight", "constraintWeight"}) {
    if (r.has(key) && !(r.number(key) >= 0.0)) r.fail(key, "must be >= 0");
  }
  const double maxIterations = r.number("maxIterations", solve.maxIterations);
  if (!(maxIterations >= 0.0) || maxIterations != std::floor(maxIterations) ||
      maxIterations > 1e6) {
    r.fail("maxIterations", "must be an integer in [0, 1000000]");
  }
  solve.maxIterations = int(maxIterations);
  solve.tolerance = r.number("tolerance", solve.tolerance);
  if (!(solve.tolerance >= 0.0)) r.fail("tolerance", "must be >= 0");
  solve.progress = r.place().progress;
  r.finish();  // a misspelt key is reported before a long solve, not after it
  DeformationGraph graph(nodes, {}, options);
  if (r.checking()) return {};  // the solve is the expensive part
  const DeformationGraphReport report = graph.solve(handles, targets, solve);
  Rig rig{std::make_shared<DeformationGraphWarp>(graph.warp()), nullptr, {}};
  // Warnings, not errors: the warp is still the best the solve found, and usable.
  if (!report.converged) {
    std::ostringstream line;
    line << r.where() << ": the deformation graph did not converge in " << report.iterations
         << " iterations (energy " << report.energies.front() << " -> " << report.energies.back()
         << "); raise 'maxIterations' or 'tolerance'";
    rig.warnings.push_back(line.str());
  }
  if (report.unconstrainedComponents > 0) {
    rig.warnings.push_back(r.where() + ": " + std::to_string(report.unconstrainedComponents) +
                           " of " + std::to_string(report.componentCount) +
                           " parts of the deformation graph (" +
                           std::to_string(report.unconstrainedNodes.size()) +
                           " nodes) are reached by no handle and stay in place");
  }
  return rig;
}

}  // namespace spacewarp::detail
