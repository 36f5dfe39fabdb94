#include <spacewarp/surface/cotan_laplacian.h>

#include <random>

#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>

#include "coords/coords_test_shapes.h"
#include "surface/surface_test_shapes.h"

namespace spacewarp {
namespace {

// A flat, irregular triangulation of the unit square: a jittered grid, so angles are obtuse
// here and there.
SurfaceMesh jitteredSquare(int n, double jitter) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-jitter, jitter);
  PolygonSoup soup;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const bool inside = i > 0 && i < n && j > 0 && j < n;
      soup.positions.push_back(
          Vec3((i + (inside ? u(rng) : 0.0)) / n, (j + (inside ? u(rng) : 0.0)) / n, 0.0));
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const auto v = static_cast<std::uint32_t>(j * (n + 1) + i);
      soup.addPolygon({v, v + 1, v + n + 2});
      soup.addPolygon({v, v + n + 2, v + n + 1});
    }
  return weldSoup(soup);
}

TEST(CotanLaplacian, IsSymmetricWithZeroRowSums) {
  const SurfaceMesh mesh = test::bar(3.0, 3);
  const Eigen::SparseMatrix<double> l = cotanLaplacian(mesh.positions, mesh.triangles);
  EXPECT_LT((Eigen::MatrixXd(l) - Eigen::MatrixXd(l).transpose()).cwiseAbs().maxCoeff(), 1e-14);
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(l.rows());
  EXPECT_LT((l * ones).cwiseAbs().maxCoeff(), 1e-13);
}

TEST(CotanLaplacian, ReproducesLinearFunctionsAndTheirDirichletEnergy) {
  const SurfaceMesh mesh = jitteredSquare(8, 0.3);
  const Eigen::SparseMatrix<double> l = cotanLaplacian(mesh.positions, mesh.triangles);
  Eigen::VectorXd f(l.rows());
  for (Eigen::Index v = 0; v < f.size(); ++v)
    f[v] = 2.0 * mesh.positions[v].x - 3.0 * mesh.positions[v].y;
  const Eigen::VectorXd lf = l * f;
  for (Eigen::Index v = 0; v < f.size(); ++v) {
    const Vec3& x = mesh.positions[v];
    const bool boundary = x.x == 0.0 || x.x == 1.0 || x.y == 0.0 || x.y == 1.0;
    if (!boundary) {
      EXPECT_NEAR(lf[v], 0.0, 1e-12) << "interior vertex " << v;
    }
  }
  // fᵀ L f = ∫ |∇f|² = (4 + 9) × area 1.
  EXPECT_NEAR(f.dot(lf), 13.0, 1e-11);
}

TEST(CotanLaplacian, IsDimensionlessAndMassScalesWithArea) {
  const SurfaceMesh mesh = jitteredSquare(5, 0.3);
  std::vector<Vec3> scaled = mesh.positions;
  for (Vec3& x : scaled) x = 1e4 * x + Vec3(1e6);
  const auto l1 = cotanLaplacian(mesh.positions, mesh.triangles);
  const auto l2 = cotanLaplacian(scaled, mesh.triangles);
  EXPECT_LT((Eigen::MatrixXd(l1) - Eigen::MatrixXd(l2)).cwiseAbs().maxCoeff(), 1e-8);
  const Eigen::VectorXd m1 = massMatrixDiagonal(mesh.positions, mesh.triangles);
  const Eigen::VectorXd m2 = massMatrixDiagonal(scaled, mesh.triangles);
  EXPECT_NEAR(m1.sum(), 1.0, 1e-12);
  EXPECT_NEAR(m2.sum(), 1e8, 1e-1);
  EXPECT_GT(m1.minCoeff(), 0.0);
}

// On the unit sphere the Laplace-Beltrami operator of the position is the mean curvature
// normal: Δx = −2 x, so M⁻¹ L x → 2 x as the sphere is refined; and the masses sum to 4π.
TEST(CotanLaplacian, ConvergesToTheMeanCurvatureNormalOfASphere) {
  double previous = 1.0;
  for (int levels : {3, 4}) {
    const SurfaceMesh mesh = weldSoup(test::icosphere(levels));
    const auto l = cotanLaplacian(mesh.positions, mesh.triangles);
    const Eigen::VectorXd mass = massMatrixDiagonal(mesh.positions, mesh.triangles);
    const Eigen::MatrixXd x = [&] {
      Eigen::MatrixXd m(Eigen::Index(mesh.vertexCount()), 3);
      for (std::size_t v = 0; v < mesh.vertexCount(); ++v)
        m.row(Eigen::Index(v)) << mesh.positions[v].x, mesh.positions[v].y, mesh.positions[v].z;
      return m;
    }();
    const Eigen::MatrixXd hn = mass.cwiseInverse().asDiagonal() * (l * x);
    const double error = (hn - 2.0 * x).rowwise().norm().maxCoeff() / 2.0;
    EXPECT_LT(error, 0.02) << "levels " << levels;
    EXPECT_LT(error, previous);
    previous = error;
    EXPECT_NEAR(mass.sum(), 4.0 * M_PI, 0.02 * 4.0 * M_PI / std::pow(4.0, levels - 3));
  }
}

TEST(MassMatrix, GivesAnObtuseTrianglesHalfAreaToTheObtuseCorner) {
  const std::vector<Vec3> p = {Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(1, 0.2, 0)};
  const std::vector<std::array<std::uint32_t, 3>> t = {{0, 1, 2}};
  const Eigen::VectorXd m = massMatrixDiagonal(p, t);
  const double area = 0.2;
  EXPECT_NEAR(m[2], area / 2, 1e-15);
  EXPECT_NEAR(m[0], area / 4, 1e-15);
  EXPECT_NEAR(m[1], area / 4, 1e-15);
}

TEST(MassMatrix, SumsToTheSurfaceAreaOfAClosedMesh) {
  const SurfaceMesh mesh = test::bar(3.0, 2);
  EXPECT_NEAR(massMatrixDiagonal(mesh.positions, mesh.triangles).sum(), 4 * 3.0 + 2.0, 1e-12);
}

TEST(CotanLaplacian, DegenerateTrianglesContributeNothingAndStayFinite) {
  // A needle (area 1e-20) next to a good triangle.
  const std::vector<Vec3> p = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0.5, 1e-20, 0)};
  const std::vector<std::array<std::uint32_t, 3>> t = {{0, 1, 2}, {0, 3, 1}};
  const Eigen::MatrixXd l = Eigen::MatrixXd(cotanLaplacian(p, t));
  EXPECT_TRUE(l.allFinite());
  EXPECT_EQ(l.row(3).cwiseAbs().sum(), 0.0);
  EXPECT_TRUE(massMatrixDiagonal(p, t).allFinite());
  EXPECT_GT(massMatrixDiagonal(p, t).minCoeff(), 0.0);
}

TEST(CotanLaplacian, RefusesBadIndicesAndNonFiniteVertices) {
  const std::vector<Vec3> p = {Vec3(0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  const std::vector<std::array<std::uint32_t, 3>> bad = {{0, 1, 3}};
  EXPECT_THROW(cotanLaplacian(p, bad), InvalidInput);
  EXPECT_THROW(massMatrixDiagonal(p, bad), InvalidInput);
  std::vector<Vec3> nan = p;
  nan[2].y = std::nan("");
  const std::vector<std::array<std::uint32_t, 3>> t = {{0, 1, 2}};
  EXPECT_THROW(cotanLaplacian(nan, t), InvalidInput);
}

}  // namespace
}  // namespace spacewarp
