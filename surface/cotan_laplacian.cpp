#include <spacewarp/surface/cotan_laplacian.h>

#include <algorithm>
#include <string>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/surface/detail/edit_problem.h>

namespace spacewarp {

namespace {

void checkTriangles(std::span<const Vec3> positions,
                    std::span<const std::array<std::uint32_t, 3>> triangles, const char* caller) {
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (std::uint32_t v : triangles[t]) {
      if (v >= positions.size()) {
        throw InvalidInput(std::string(caller) + ": triangle " + std::to_string(t) +
                           " refers to vertex " + std::to_string(v) + " of " +
                           std::to_string(positions.size()));
      }
      if (!isFinite(positions[v])) {
        throw InvalidInput(std::string(caller) + ": vertex " + std::to_string(v) +
                           " is not finite");
      }
    }
}

}  // namespace

Eigen::SparseMatrix<double> cotanLaplacian(
    std::span<const Vec3> positions, std::span<const std::array<std::uint32_t, 3>> triangles) {
  checkTriangles(positions, triangles, "cotanLaplacian");
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(triangles.size() * 12);
  for (const auto& t : triangles) {
    const Vec3 p[3] = {positions[t[0]], positions[t[1]], positions[t[2]]};
    if (detail::isDegenerateTriangle(p[0], p[1], p[2])) continue;
    const double twiceArea = glm::length(glm::cross(p[1] - p[0], p[2] - p[0]));
    for (int c = 0; c < 3; ++c) {
      const int j = (c + 1) % 3, k = (c + 2) % 3;
      // cot of the angle at corner c, which faces the edge jk.
      const double half = 0.5 * glm::dot(p[j] - p[c], p[k] - p[c]) / twiceArea;
      entries.emplace_back(t[j], t[k], -half);
      entries.emplace_back(t[k], t[j], -half);
      entries.emplace_back(t[j], t[j], half);
      entries.emplace_back(t[k], t[k], half);
    }
  }
  Eigen::SparseMatrix<double> l(static_cast<Eigen::Index>(positions.size()),
                                static_cast<Eigen::Index>(positions.size()));
  l.setFromTriplets(entries.begin(), entries.end());
  return l;
}

Eigen::VectorXd massMatrixDiagonal(std::span<const Vec3> positions,
                                   std::span<const std::array<std::uint32_t, 3>> triangles) {
  checkTriangles(positions, triangles, "massMatrixDiagonal");
  Eigen::VectorXd mass = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(positions.size()));
  for (const auto& t : triangles) {
    const Vec3 p[3] = {positions[t[0]], positions[t[1]], positions[t[2]]};
    const double area = 0.5 * glm::length(glm::cross(p[1] - p[0], p[2] - p[0]));
    if (detail::isDegenerateTriangle(p[0], p[1], p[2])) {
      for (std::uint32_t v : t) mass[v] += area / 3.0;
      continue;
    }
    int obtuse = -1;
    for (int c = 0; c < 3; ++c)
      if (glm::dot(p[(c + 1) % 3] - p[c], p[(c + 2) % 3] - p[c]) < 0.0) obtuse = c;
    for (int c = 0; c < 3; ++c) {
      if (obtuse >= 0) {
        mass[t[c]] += obtuse == c ? area / 2.0 : area / 4.0;
        continue;
      }
      // Voronoi area of corner c: (|e_cj|² cot θ_k + |e_ck|² cot θ_j) / 8.
      const int j = (c + 1) % 3, k = (c + 2) % 3;
      const double twiceArea = 2.0 * area;
      const double cotJ = glm::dot(p[c] - p[j], p[k] - p[j]) / twiceArea;
      const double cotK = glm::dot(p[c] - p[k], p[j] - p[k]) / twiceArea;
      const Vec3 ej = p[j] - p[c], ek = p[k] - p[c];
      mass[t[c]] += (glm::dot(ej, ej) * cotK + glm::dot(ek, ek) * cotJ) / 8.0;
    }
  }
  double smallest = std::numeric_limits<double>::infinity();
  for (double m : mass)
    if (m > 0.0) smallest = std::min(smallest, m);
  if (!std::isfinite(smallest)) smallest = 1.0;
  for (double& m : mass)
    if (!(m > 0.0)) m = smallest;
  return mass;
}

}  // namespace spacewarp
