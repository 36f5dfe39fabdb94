#include <spacewarp/surface/detail/edit_problem.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/geometry.h>
#include <spacewarp/surface/cotan_laplacian.h>

namespace spacewarp::detail {

bool isDegenerateTriangle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const double longest2 =
      std::max({glm::dot(b - a, b - a), glm::dot(c - b, c - b), glm::dot(a - c, a - c)});
  return !(glm::length(glm::cross(b - a, c - a)) > 1e-12 * longest2);
}

std::vector<std::uint32_t> vertexComponents(std::span<const Vec3> positions,
                                            std::span<const std::array<std::uint32_t, 3>> triangles,
                                            std::size_t& count, bool skipDegenerate) {
  const std::size_t n = positions.size();
  std::vector<std::uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  std::vector<bool> inTriangle(n, false);
  for (const auto& t : triangles) {
    if (skipDegenerate && isDegenerateTriangle(positions[t[0]], positions[t[1]], positions[t[2]]))
      continue;
    for (std::uint32_t v : t) inTriangle[v] = true;
    for (int c = 1; c < 3; ++c) {
      const std::uint32_t a = find(t[0]), b = find(t[c]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  }
  std::vector<std::uint32_t> component(n, std::uint32_t(-1));
  std::vector<std::uint32_t> ofRoot(n, std::uint32_t(-1));
  count = 0;
  for (std::uint32_t v = 0; v < n; ++v) {
    if (!inTriangle[v]) continue;
    const std::uint32_t r = find(v);
    if (ofRoot[r] == std::uint32_t(-1)) ofRoot[r] = static_cast<std::uint32_t>(count++);
    component[v] = ofRoot[r];
  }
  std::uint32_t next = static_cast<std::uint32_t>(count);
  for (std::uint32_t v = 0; v < n; ++v)
    if (!inTriangle[v]) component[v] = next++;
  return component;
}

Eigen::MatrixXd toMatrix(std::span<const Vec3> points) {
  Eigen::MatrixXd m(static_cast<Eigen::Index>(points.size()), 3);
  for (std::size_t i = 0; i < points.size(); ++i)
    m.row(static_cast<Eigen::Index>(i)) << points[i].x, points[i].y, points[i].z;
  return m;
}

void checkSurfaceScale(std::span<const Vec3> positions, const std::string& caller) {
  constexpr double kLimit = 1e100;
  for (std::size_t v = 0; v < positions.size(); ++v)
    if (!(maxAbs(positions[v]) < kLimit)) {
      throw InvalidInput(caller + ": vertex " + std::to_string(v) +
                         (isFinite(positions[v]) ? " is beyond 1e100 in magnitude (squared lengths "
                                                   "would overflow)"
                                                 : " is not finite"));
    }
}

EditProblem makeEditProblem(std::span<const Vec3> positions,
                            std::span<const std::array<std::uint32_t, 3>> triangles,
                            std::span<const std::uint32_t> constrained, const std::string& caller) {
  const std::size_t n = positions.size();
  if (n == 0 || triangles.empty()) throw InvalidInput(caller + ": the mesh has no triangle");
  if (constrained.empty()) {
    throw InvalidInput(caller + ": no constrained vertex (give at least one handle region)");
  }
  checkSurfaceScale(positions, caller);
  EditProblem p;
  p.rest.assign(positions.begin(), positions.end());
  p.triangles.assign(triangles.begin(), triangles.end());
  p.laplacian = cotanLaplacian(positions, triangles);  // checks the triangles' indices
  p.diagonal = boundingBox(positions).diagonal();
  p.slot.assign(n, 0);
  std::vector<bool> isConstrained(n, false);
  for (std::size_t k = 0; k < constrained.size(); ++k) {
    const std::uint32_t v = constrained[k];
    if (v >= n) {
      throw InvalidInput(caller + ": constrained vertex " + std::to_string(v) + " (entry " +
                         std::to_string(k) + ") is out of range: the mesh has " +
                         std::to_string(n) + " vertices");
    }
    if (isConstrained[v]) {
      throw InvalidInput(caller + ": vertex " + std::to_string(v) +
                         " is constrained twice (entry " + std::to_string(k) + ")");
    }
    isConstrained[v] = true;
  }
  p.constrained.assign(constrained.begin(), constrained.end());
  // Components the energy cannot place (no constrained vertex) are held at rest.
  std::size_t count = 0;
  const auto component = vertexComponents(positions, triangles, count, true);
  if (count == 0) {
    throw InvalidInput(caller + ": every triangle of the mesh is degenerate (no area)");
  }
  std::vector<bool> anchored(n, false);
  for (std::uint32_t v : constrained) anchored[component[v]] = true;
  for (std::uint32_t v = 0; v < n; ++v) {
    if (isConstrained[v]) continue;
    if (!anchored[component[v]]) {
      p.held.push_back(v);
    } else {
      p.slot[v] = static_cast<std::int64_t>(p.freeVertices.size());
      p.freeVertices.push_back(v);
    }
  }
  for (std::size_t k = 0; k < constrained.size(); ++k)
    p.slot[constrained[k]] = -static_cast<std::int64_t>(k) - 1;
  for (std::size_t k = 0; k < p.held.size(); ++k)
    p.slot[p.held[k]] = -static_cast<std::int64_t>(constrained.size() + k) - 1;
  return p;
}

namespace {

Eigen::SparseMatrix<double> block(const EditProblem& p, const Eigen::SparseMatrix<double>& m,
                                  bool fixedColumns) {
  std::vector<Eigen::Triplet<double>> entries;
  for (Eigen::Index c = 0; c < m.outerSize(); ++c) {
    const std::int64_t sc = p.slot[static_cast<std::size_t>(c)];
    if (fixedColumns != (sc < 0)) continue;
    const std::int64_t col = sc < 0 ? -sc - 1 : sc;
    for (Eigen::SparseMatrix<double>::InnerIterator it(m, c); it; ++it) {
      const std::int64_t sr = p.slot[static_cast<std::size_t>(it.row())];
      if (sr < 0 || (!fixedColumns && sr < col)) continue;
      entries.emplace_back(static_cast<int>(sr), static_cast<int>(col), it.value());
    }
  }
  const auto rows = static_cast<Eigen::Index>(p.freeVertices.size());
  Eigen::SparseMatrix<double> out(rows,
                                  fixedColumns ? static_cast<Eigen::Index>(p.fixedCount()) : rows);
  out.setFromTriplets(entries.begin(), entries.end());
  return out;
}

}  // namespace

Eigen::SparseMatrix<double> EditProblem::freeBlockLower(
    const Eigen::SparseMatrix<double>& m) const {
  return block(*this, m, false);
}

Eigen::SparseMatrix<double> EditProblem::freeFixedBlock(
    const Eigen::SparseMatrix<double>& m) const {
  return block(*this, m, true);
}

Eigen::MatrixXd EditProblem::fixedPositions(std::span<const Vec3> targets,
                                            const std::string& caller) const {
  if (targets.size() != constrained.size()) {
    throw InvalidInput(caller + ": " + std::to_string(targets.size()) + " targets for " +
                       std::to_string(constrained.size()) + " constrained vertices");
  }
  Eigen::MatrixXd fixed(static_cast<Eigen::Index>(fixedCount()), 3);
  for (std::size_t k = 0; k < targets.size(); ++k) {
    if (!isFinite(targets[k])) {
      throw InvalidInput(caller + ": the target of constrained vertex " +
                         std::to_string(constrained[k]) + " (entry " + std::to_string(k) +
                         ") is not finite");
    }
    fixed.row(static_cast<Eigen::Index>(k)) << targets[k].x, targets[k].y, targets[k].z;
  }
  for (std::size_t k = 0; k < held.size(); ++k) {
    const Vec3& x = rest[held[k]];
    fixed.row(static_cast<Eigen::Index>(constrained.size() + k)) << x.x, x.y, x.z;
  }
  return fixed;
}

std::vector<Vec3> EditProblem::assemble(const Eigen::MatrixXd& freePositions,
                                        const Eigen::MatrixXd& fixed) const {
  std::vector<Vec3> out(rest.size());
  for (std::size_t v = 0; v < out.size(); ++v) {
    const std::int64_t s = slot[v];
    const auto& row = s >= 0 ? freePositions.row(s) : fixed.row(-s - 1);
    out[v] = Vec3(row(0), row(1), row(2));
  }
  return out;
}

}  // namespace spacewarp::detail
