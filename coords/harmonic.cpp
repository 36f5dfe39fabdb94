#include <spacewarp/coords/harmonic.h>

// The solve
// =========
// For a tet with corners p_0..p_3 and volume V, the gradients g_a of the barycentric
// coordinates are constant (rows of [p1 − p0, p2 − p0, p3 − p0]⁻¹, g_0 = −g_1 − g_2 − g_3), and
// the linear-FEM stiffness matrix is K_ab = V g_a · g_b (the "cotangent" Laplacian: off the
// diagonal, −(1/6) Σ over the tets of edge ab of the length of the opposite edge times the
// cotangent of the dihedral angle there). With the vertices split into interior I and boundary
// B, the coordinate functions solve K_II U_I = −K_IB U_B, where U_B holds the Dirichlet values
// (one row per boundary vertex, at most 3 non-zeros). K_II is symmetric positive definite; it is
// factorised once by CHOLMOD's supernodal Cholesky (chosen by measurement, see solveValues), and
// the k right-hand sides are solved in fixed blocks of kBlock columns, each a multi-column
// (BLAS-3) solve that the BLAS runs in parallel. Nothing depends on the TBB thread count.
//
// Everything runs in the cage's frame (TetMesh::localVertices, Cage::frame()): TetGen, the
// assembly and point location. In world units a cage far from the origin (a unit box at 1e8)
// loses most of its digits to the offset in every p1 − p0 and x − p0, and its weights went wrong
// by up to 0.3. The coordinates are invariant under the frame's similarity, so nothing maps back
// except the gradients (divided by the frame's scale) and the mesh's world vertices.
//
// Assembly runs over the tets in order (serially: it costs a few percent of the solve), so
// the matrix and right-hand sides are bit-identical from run to run.

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <Eigen/Cholesky>
#include <Eigen/SparseCore>

#include <spacewarp/coords/detail/harmonic_file.h>
#include <spacewarp/coords/detail/outside_hint.h>
#include <spacewarp/coords/harmonic_warp.h>
#include <spacewarp/coords/tet_locator.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/detail/serial_blas.h>
#include <spacewarp/core/detail/sparse_cholesky.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

// Right-hand-side columns per solve call (fixed, for determinism).
constexpr std::size_t kBlock = 32;
// Points per parallel evaluation task.
constexpr std::size_t kPointsPerTask = 256;
// Mean tet volume of TetGen's refinement under a volume bound a, as a fraction of a (measured
// on the armadillo cage with radius-edge bound 2: 0.43 at 200k tets, ~0.3 for the small test
// cages at 1k–10k tets).
constexpr double kMeanVolumeFraction = 0.43;

// Peak memory, fitted to the peak RSS of meshing and solving (cube and bar cages of 8 to 20
// vertices at 10k to 2.6M tets, and TetGen alone on a 20,736-triangle cage). Each term bounds
// its measurement by 1.1 to 1.5 times; with the mesh size predicted from the target (below),
// the whole estimate came to 1.7 to 2.3 times the process's peak RSS (cage.obj of the demo at
// 100k to 1.6M tets, a cube at 1.6M, a 602-vertex box at 50k), most for small meshes, where
// OpenBLAS's buffer (address space, mostly untouched) weighs most:
// - the mesh (TetGen's pools, then the TetMesh), the Laplacian's triplets and the point locator
//   take about 250 bytes a tet, of which 160 after meshing;
constexpr double kBytesPerTet = 250.0, kSolveBytesPerTet = 160.0;
// - the supernodal Cholesky factor fills like tets^1.4: 1.2 GB at 1.3M tets, 3.1 GB at 2.6M;
constexpr double kFactorBytes = 4.0, kFactorExponent = 1.4;
// - TetGen's copy of the cage (one facet per triangle) about 4 kB a cage triangle;
constexpr double kBytesPerCageTriangle = 4096.0;
// - the values, right-hand sides and solution are three dense arrays of mesh vertices × cage
//   vertices doubles, and OpenBLAS maps its work buffer.
// Before meshing, the mesh's size follows from the volume bound: TetGen's quality bound adds
// tets near small features (up to ~4 a cage triangle: 74k tets for that cage at any target
// below that), and a mesh has 4 to 6 tets a vertex besides the cage's own vertices.
double solveBytes(double tets, double meshVertices, double cageVertices) {
  return kSolveBytesPerTet * tets + kFactorBytes * std::pow(tets, kFactorExponent) +
         3.0 * sizeof(double) * meshVertices * cageVertices +
         static_cast<double>(detail::blasWorkBufferBytes());
}

double expectedTets(const Cage& cage, double volumeBound) {
  return cage.volume() / (kMeanVolumeFraction * volumeBound) + 4.0 * cage.triangleCount();
}

using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

std::string number(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", value);
  return text;
}

std::string pointText(const Vec3& x) {
  return "(" + number(x.x) + ", " + number(x.y) + ", " + number(x.z) + ")";
}

// Barycentric coordinates of the projection of x on the plane of triangle (a, b, c), clamped to
// the triangle and renormalised.
std::array<double, 3> faceBarycentric(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& x) {
  const Vec3 n = glm::cross(b - a, c - a);
  std::array<double, 3> w = {std::max(0.0, glm::dot(n, glm::cross(b - x, c - x))),
                             std::max(0.0, glm::dot(n, glm::cross(c - x, a - x))),
                             std::max(0.0, glm::dot(n, glm::cross(a - x, b - x)))};
  const double sum = w[0] + w[1] + w[2];
  for (double& v : w) v /= sum;
  return w;
}

// The point of triangle (a, b, c) nearest to x, as barycentric coordinates (Voronoi regions of
// the vertices, edges and face).
std::array<double, 3> nearestOnTriangle(const Vec3& a, const Vec3& b, const Vec3& c,
                                        const Vec3& x) {
  const Vec3 ab = b - a, ac = c - a, ax = x - a;
  const double d1 = glm::dot(ab, ax), d2 = glm::dot(ac, ax);
  if (d1 <= 0.0 && d2 <= 0.0) return {1.0, 0.0, 0.0};
  const Vec3 bx = x - b;
  const double d3 = glm::dot(ab, bx), d4 = glm::dot(ac, bx);
  if (d3 >= 0.0 && d4 <= d3) return {0.0, 1.0, 0.0};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double t = d1 / (d1 - d3);
    return {1.0 - t, t, 0.0};
  }
  const Vec3 cx = x - c;
  const double d5 = glm::dot(ab, cx), d6 = glm::dot(ac, cx);
  if (d6 >= 0.0 && d5 <= d6) return {0.0, 0.0, 1.0};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double t = d2 / (d2 - d6);
    return {1.0 - t, 0.0, t};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {0.0, 1.0 - t, t};
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {1.0 - v - w, v, w};
}

// Projects the row u (k values of the coordinate functions at a point x) onto the coordinates
// that are non-negative and keep partition of unity and linear reproduction: the minimiser of
// ½|w − u|² subject to w ≥ 0, Σ w_c = 1, Σ w_c (p_c − x) / s = 0 (s: the cage diagonal). Its
// dual solution is w = max(0, u + Aᵀλ) for the 4 × k constraint matrix A; λ solves
// A max(0, u + Aᵀλ) = b, found by a damped semismooth Newton iteration (4 unknowns). Returns
// false, leaving u unchanged, if it does not converge (x outside the cage vertices' hull).
bool projectNonNegative(std::span<double> u, std::span<const Vec3> cageVertices, const Vec3& x,
                        double scale) {
  const std::size_t k = u.size();
  std::vector<Eigen::Vector4d> a(k);
  for (std::size_t c = 0; c < k; ++c) {
    const Vec3 d = (cageVertices[c] - x) / scale;
    a[c] = Eigen::Vector4d(1.0, d.x, d.y, d.z);
  }
  const Eigen::Vector4d b(1.0, 0.0, 0.0, 0.0);
  // φ(λ) = ½ |max(0, u + Aᵀλ)|² − b·λ is convex; its gradient is the constraint residual F and
  // its generalised Hessian Σ_{active c} a_c a_cᵀ. Newton steps with an Armijo line search on φ.
  auto evaluate = [&](const Eigen::Vector4d& lambda, Eigen::Vector4d* gradient,
                      Eigen::Matrix4d* hessian) {
    double phi = -b.dot(lambda);
    if (gradient) *gradient = -b;
    if (hessian) hessian->setZero();
    for (std::size_t c = 0; c < k; ++c) {
      const double w = u[c] + a[c].dot(lambda);
      if (w <= 0.0) continue;
      phi += 0.5 * w * w;
      if (gradient) *gradient += w * a[c];
      if (hessian) *hessian += a[c] * a[c].transpose();
    }
    return phi;
  };
  Eigen::Vector4d lambda = Eigen::Vector4d::Zero(), f;
  Eigen::Matrix4d hessian;
  double phi = evaluate(lambda, &f, &hessian);
  constexpr double kTolerance = 1e-15;
  for (int iteration = 0; iteration < 200 && f.norm() > kTolerance; ++iteration) {
    hessian.diagonal().array() += 1e-12 * (1.0 + hessian.trace());
    const Eigen::Vector4d step = hessian.ldlt().solve(-f);
    const double slope = f.dot(step);
    if (!(slope < 0.0)) break;
    double t = 1.0;
    bool accepted = false;
    for (int halving = 0; halving < 60; ++halving, t *= 0.5) {
      const Eigen::Vector4d next = lambda + t * step;
      Eigen::Vector4d fNext;
      const double phiNext = evaluate(next, &fNext, nullptr);
      // Near the solution φ's decrease (about |F|² / |H|) falls below φ's round-off and the
      // Armijo test cannot see it: a step that halves the residual is then taken too. Without
      // it, on the armadillo cage at precision 3, 223 of 1,173 rows crawled through 200
      // iterations (10,000 evaluations each, 80% of the set-up) and were left negative.
      if (phiNext <= phi + 1e-4 * t * slope || fNext.norm() <= 0.5 * f.norm()) {
        lambda = next;
        accepted = true;
        break;
      }
    }
    if (!accepted) break;
    phi = evaluate(lambda, &f, &hessian);
  }
  const double norm = f.norm();
  if (!(norm <= 1e-12)) return false;
  for (std::size_t c = 0; c < k; ++c) u[c] = std::max(0.0, u[c] + a[c].dot(lambda));
  return true;
}

}  // namespace

namespace {
std::atomic<std::size_t> solveCount{0};  // for detail::harmonicSolveCount()
}  // namespace

std::size_t detail::harmonicSolveCount() { return solveCount.load(); }

struct HarmonicCoordinates::Impl {
  std::shared_ptr<const Cage> cage;
  HarmonicOptions options;
  TetMesh mesh;
  std::vector<double> values;  // mesh vertex count × k, row-major
  double volumeBound = 0.0;
  std::unique_ptr<TetLocator> locator;

  std::size_t k() const { return cage->vertexCount(); }

  void rowAt(const Vec3& x, std::span<double> row, bool& outside) const;
  void nearestRow(const Vec3& x, std::span<double> row) const;
};

void HarmonicCoordinates::Impl::rowAt(const Vec3& x, std::span<double> row, bool& outside) const {
  const TetLocator::Hit hit = locator->locate(mesh.frame.toLocal(x));
  const std::size_t n = k();
  if (!hit.found) {
    outside = true;
    if (options.outside == HarmonicOutsidePolicy::NearestPoint) nearestRow(x, row);
    return;
  }
  outside = false;
  const auto& tet = mesh.tets[hit.tet];
  const double* u0 = &values[tet[0] * n];
  const double* u1 = &values[tet[1] * n];
  const double* u2 = &values[tet[2] * n];
  const double* u3 = &values[tet[3] * n];
  const double b0 = hit.barycentric[0], b1 = hit.barycentric[1], b2 = hit.barycentric[2],
               b3 = hit.barycentric[3];
  double* r = row.data();
  for (std::size_t c = 0; c < n; ++c) r[c] = b0 * u0[c] + b1 * u1[c] + b2 * u2[c] + b3 * u3[c];
}

void HarmonicCoordinates::Impl::nearestRow(const Vec3& world, std::span<double> row) const {
  const std::span<const Vec3> vertices(mesh.localVertices.data(), k());  // the cage's, local
  const Vec3 x = mesh.frame.toLocal(world);
  const auto triangles = cage->triangles();
  double bestDist = std::numeric_limits<double>::infinity();
  std::size_t best = 0;
  std::array<double, 3> bestW{};
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const Vec3 &a = vertices[triangles[t].x], &b = vertices[triangles[t].y],
               &c = vertices[triangles[t].z];
    const std::array<double, 3> w = nearestOnTriangle(a, b, c, x);
    const Vec3 p = w[0] * a + w[1] * b + w[2] * c;
    const double d = glm::dot(p - x, p - x);
    if (d < bestDist) {
      bestDist = d;
      best = t;
      bestW = w;
    }
  }
  std::fill(row.begin(), row.end(), 0.0);
  row[triangles[best].x] += bestW[0];
  row[triangles[best].y] += bestW[1];
  row[triangles[best].z] += bestW[2];
}

std::size_t harmonicPrecisionTets(double precision) {
  if (!(precision >= kHarmonicMinPrecision && precision <= kHarmonicMaxPrecision)) {
    throw InvalidInput("harmonic precision must be a number in [" +
                       std::to_string(kHarmonicMinPrecision) + ", " +
                       std::to_string(kHarmonicMaxPrecision) + "], got " + number(precision));
  }
  // Whole levels exactly (as when only they existed): 3125 · 4^(p − 2) for p ≥ 2, 781 at 1.
  if (precision == std::floor(precision)) {
    const int level = static_cast<int>(precision);
    return level == 1 ? 781 : std::size_t{3125} << (2 * (level - 2));
  }
  return static_cast<std::size_t>(std::llround(200000.0 * std::pow(4.0, precision - 5.0)));
}

double HarmonicCoordinates::memoryEstimate(const Cage& cage, const HarmonicOptions& options) {
  const double tets = expectedTets(cage, tetVolumeBound(cage, options));
  const double k = static_cast<double>(cage.vertexCount());
  return kBytesPerCageTriangle * static_cast<double>(cage.triangleCount()) +
         (kBytesPerTet - kSolveBytesPerTet) * tets + solveBytes(tets, tets / 4.0 + k, k);
}

double HarmonicCoordinates::tetVolumeBound(const Cage& cage, const HarmonicOptions& options) {
  if (options.maxTetVolumeFraction > 0.0) return options.maxTetVolumeFraction * cage.volume();
  return cage.volume() / (kMeanVolumeFraction * static_cast<double>(options.targetTetCount));
}

namespace {

void checkOptions(const HarmonicOptions& options) {
  if (options.targetTetCount < 1)
    throw InvalidInput("HarmonicCoordinates: targetTetCount must be >= 1");
  if (!(std::isfinite(options.maxTetVolumeFraction) && options.maxTetVolumeFraction >= 0.0 &&
        options.maxTetVolumeFraction <= 1.0)) {
    throw InvalidInput(
        "HarmonicCoordinates: maxTetVolumeFraction must be in [0, 1] (relative to the cage "
        "volume), got " +
        number(options.maxTetVolumeFraction));
  }
  if (options.outside != HarmonicOutsidePolicy::Throw &&
      options.outside != HarmonicOutsidePolicy::NearestPoint)
    throw InvalidInput("HarmonicCoordinates: unknown outside policy");
}

// The Dirichlet values of boundary vertex v: (cage vertex, weight) pairs, at most 3.
std::size_t boundaryValues(const Cage& cage, const TetMesh& mesh, std::size_t v,
                           std::array<std::pair<std::uint32_t, double>, 3>& out) {
  if (v < cage.vertexCount()) {
    out[0] = {static_cast<std::uint32_t>(v), 1.0};
    return 1;
  }
  const Triangle& tri = cage.triangles()[static_cast<std::size_t>(mesh.boundaryTriangle[v])];
  const std::vector<Vec3>& p = mesh.localVertices;
  const auto w = faceBarycentric(p[tri.x], p[tri.y], p[tri.z], p[v]);
  out[0] = {tri.x, w[0]};
  out[1] = {tri.y, w[1]};
  out[2] = {tri.z, w[2]};
  return 3;
}

// K_II (lower triangle) and the right-hand sides −K_IB U_B of the interior vertices.
struct Laplacian {
  SparseMatrix a;
  Eigen::MatrixXd rhs;  // interior vertices × k
};

// Assembles the Laplacian tet by tet, in order. `interior`: per mesh vertex its interior
// index, or −1 on the boundary; nI interior vertices.
Laplacian assembleLaplacian(const Cage& cage, const TetMesh& mesh, const std::vector<int>& interior,
                            int nI) {
  const std::size_t k = cage.vertexCount();
  std::array<std::pair<std::uint32_t, double>, 3> bv{};
  std::vector<Eigen::Triplet<double, int>> triplets;
  triplets.reserve(mesh.tets.size() * 10);
  Laplacian system{SparseMatrix(nI, nI), Eigen::MatrixXd::Zero(nI, static_cast<Eigen::Index>(k))};
  const std::vector<Vec3>& p = mesh.localVertices;
  for (const auto& tet : mesh.tets) {
    // A flat tet adds nothing: its cotangents would be round-off (and the locator never finds
    // it).
    if (isFlatTet(p[tet[0]], p[tet[1]], p[tet[2]], p[tet[3]])) continue;
    const Mat3 d(p[tet[1]] - p[tet[0]], p[tet[2]] - p[tet[0]], p[tet[3]] - p[tet[0]]);
    const double det = glm::determinant(d);
    const Mat3 inv = glm::inverse(d);
    Vec3 g[4];
    for (int i = 0; i < 3; ++i) g[i + 1] = Vec3(inv[0][i], inv[1][i], inv[2][i]);
    g[0] = -(g[1] + g[2] + g[3]);
    const double volume = det / 6.0;
    for (int a = 0; a < 4; ++a) {
      const int ia = interior[tet[static_cast<std::size_t>(a)]];
      if (ia < 0) continue;
      for (int b = 0; b < 4; ++b) {
        const std::uint32_t vb = tet[static_cast<std::size_t>(b)];
        const double kab = volume * glm::dot(g[a], g[b]);
        const int ib = interior[vb];
        if (ib >= 0) {
          if (ib <= ia) triplets.emplace_back(ia, ib, kab);
          continue;
        }
        const std::size_t count = boundaryValues(cage, mesh, vb, bv);
        for (std::size_t j = 0; j < count; ++j) system.rhs(ia, bv[j].first) -= kab * bv[j].second;
      }
    }
  }
  system.a.setFromTriplets(triplets.begin(), triplets.end());
  return system;
}

// CHOLMOD's supernodal Cholesky (BLAS-3 on the dense supernodes): on the armadillo cage at
// ~190k tets (21k interior vertices) it factorises in 0.7 s and solves the 110 right-hand
// sides in 0.2 s, where Eigen's simplicial LDLᵀ took 1.4 s and 1.9 s (one thread; 1 s with
// the columns spread over two threads). The wrapper runs the BLAS single-threaded
// (bit-identical results for any OPENBLAS_NUM_THREADS) and turns CHOLMOD failures into
// SolverError; CHOLMOD's default ordering, as Eigen's wrapper left it before.
detail::SparseCholesky factoriseLaplacian(const SparseMatrix& a) {
  detail::SparseCholesky cholesky(
      {"HarmonicCoordinates",
       "use a coarser mesh (a smaller targetTetCount or a larger maxTetVolumeFraction)",
       detail::CholeskyOrdering::CholmodDefault});
  cholesky.analyzePattern(a);
  if (!cholesky.factorize(a)) {
    throw SolverError("HarmonicCoordinates: the factorisation of the Laplacian of " +
                      std::to_string(a.rows()) + " interior vertices failed");
  }
  return cholesky;
}

// Blocks of kBlock columns, one after the other: every block is a BLAS-3 solve, and the fixed
// blocks keep the result independent of any thread count. Advances `progress` per block.
Eigen::MatrixXd solveBlocks(detail::SparseCholesky& cholesky, const Eigen::MatrixXd& rhs,
                            ProgressTracker& progress) {
  const std::size_t k = static_cast<std::size_t>(rhs.cols());
  const std::size_t blocks = (k + kBlock - 1) / kBlock;
  Eigen::MatrixXd x(rhs.rows(), rhs.cols());
  for (std::size_t blk = 0; blk < blocks; ++blk) {
    const auto c0 = static_cast<Eigen::Index>(blk * kBlock);
    const auto cols = static_cast<Eigen::Index>(std::min(kBlock, k - blk * kBlock));
    const Eigen::MatrixXd part = rhs.middleCols(c0, cols);
    x.middleCols(c0, cols) = cholesky.solve(part);
    progress.advance();
  }
  return x;
}

// Projects every row of `values` (n × k) with a negative entry (see projectNonNegative).
void projectNegativeRows(std::vector<double>& values, const Cage& cage, const TetMesh& mesh) {
  const std::size_t n = mesh.vertices.size(), k = cage.vertexCount();
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, n, 1024), [&](const tbb::blocked_range<std::size_t>& r) {
        for (std::size_t v = r.begin(); v != r.end(); ++v) {
          const std::span<double> row(values.data() + v * k, k);
          if (*std::min_element(row.begin(), row.end()) < 0.0)
            projectNonNegative(row, std::span(mesh.localVertices.data(), k), mesh.localVertices[v],
                               cage.diagonal() / mesh.frame.scale);
        }
      });
}

// Solves for the coordinate values at every mesh vertex (n × k, row-major): the boundary rows
// are their Dirichlet values, the interior rows solve the Laplacian.
std::vector<double> solveValues(const Cage& cage, const TetMesh& mesh, bool nonNegative,
                                const ProgressCallback& progress) {
  const std::size_t n = mesh.vertices.size(), k = cage.vertexCount();
  // The mesh is made; the solve is the larger part, now known exactly.
  detail::checkMemory(solveBytes(static_cast<double>(mesh.tets.size()), static_cast<double>(n),
                                 static_cast<double>(k)),
                      "HarmonicCoordinates: solving for " + std::to_string(k) +
                          " cage vertices on a mesh of " + std::to_string(n) + " vertices (" +
                          std::to_string(mesh.tets.size()) + " tets)");
  std::vector<double> values(n * k, 0.0);
  // Interior numbering.
  std::vector<int> interior(n, -1);
  int nI = 0;
  for (std::size_t v = 0; v < n; ++v)
    if (mesh.boundaryTriangle[v] < 0) interior[v] = nI++;
  // Boundary rows.
  std::array<std::pair<std::uint32_t, double>, 3> bv{};
  for (std::size_t v = 0; v < n; ++v) {
    if (interior[v] >= 0) continue;
    const std::size_t count = boundaryValues(cage, mesh, v, bv);
    for (std::size_t j = 0; j < count; ++j) values[v * k + bv[j].first] += bv[j].second;
  }
  if (nI == 0) return values;

  ProgressTracker factorise(progress, "factorise", 2);
  const Laplacian system = assembleLaplacian(cage, mesh, interior, nI);
  factorise.advance();
  detail::SparseCholesky cholesky = factoriseLaplacian(system.a);
  factorise.finish();

  ProgressTracker solve(progress, "solve", (k + kBlock - 1) / kBlock);
  const Eigen::MatrixXd x = solveBlocks(cholesky, system.rhs, solve);
  for (std::size_t v = 0; v < n; ++v) {
    if (interior[v] < 0) continue;
    for (std::size_t c = 0; c < k; ++c)
      values[v * k + c] = x(interior[v], static_cast<Eigen::Index>(c));
  }
  if (nonNegative) projectNegativeRows(values, cage, mesh);
  solve.finish();
  return values;
}

// The point locator, in the cage's frame. Its slack is the round-off of a query point's world
// coordinates (a few ulps of the largest), in frame units: points on the cage surface far from
// the origin are on it only to that precision, which can exceed the relative tolerance.
std::unique_ptr<TetLocator> makeLocator(const TetMesh& mesh) {
  const double reach = maxAbs(mesh.frame.center) + mesh.frame.scale;
  const double slack = 16.0 * std::numeric_limits<double>::epsilon() * reach / mesh.frame.scale;
  return std::make_unique<TetLocator>(mesh.localVertices, mesh.tets, 1e-10, slack);
}

/// The coordinates' state from a decoded harmonic file (a file on disk or an archive's bytes);
/// the solve's radius-edge ratio is the file's. A template so it may name the private Impl.
template <class Impl>
std::unique_ptr<Impl> implFromFile(const HarmonicOptions& options, detail::HarmonicFileData file,
                                   std::shared_ptr<const Cage> cage) {
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  impl->options.radiusEdgeRatio = file.radiusEdgeRatio;
  impl->volumeBound = file.volumeBound;
  impl->mesh = std::move(file.mesh);
  impl->values = std::move(file.values);
  impl->cage = std::move(cage);
  return impl;
}

}  // namespace

HarmonicCoordinates::HarmonicCoordinates(FromImpl, std::unique_ptr<Impl> impl) {
  impl->locator = makeLocator(impl->mesh);
  impl_ = std::move(impl);
}

HarmonicCoordinates::HarmonicCoordinates(std::shared_ptr<const Cage> cage,
                                         const HarmonicOptions& options,
                                         const ProgressCallback& progress) {
  if (!cage) throw InvalidInput("HarmonicCoordinates: the cage is null");
  checkOptions(options);
  auto impl = std::make_unique<Impl>();
  impl->cage = std::move(cage);
  impl->options = options;
  impl->volumeBound = tetVolumeBound(*impl->cage, options);
  // Before meshing: an absurd target (a billion tets) is refused at once, not after TetGen has
  // filled the memory.
  detail::checkMemory(
      memoryEstimate(*impl->cage, options),
      "HarmonicCoordinates: meshing the cage (" + std::to_string(impl->cage->vertexCount()) +
          " vertices) into about " +
          std::to_string(std::llround(expectedTets(*impl->cage, impl->volumeBound))) +
          " tets and solving");
  impl->mesh =
      tetrahedraliseCage(*impl->cage, {options.radiusEdgeRatio, impl->volumeBound}, progress);
  impl->values = solveValues(*impl->cage, impl->mesh, options.nonNegative, progress);
  ++solveCount;
  impl->locator = makeLocator(impl->mesh);
  impl_ = std::move(impl);
}

HarmonicCoordinates::~HarmonicCoordinates() = default;

std::size_t HarmonicCoordinates::controlPointCount() const { return impl_->k(); }
std::span<const Vec3> HarmonicCoordinates::restControlPoints() const {
  return impl_->cage->vertices();
}
const Cage& HarmonicCoordinates::cage() const { return *impl_->cage; }
const HarmonicOptions& HarmonicCoordinates::options() const { return impl_->options; }
const TetMesh& HarmonicCoordinates::mesh() const { return impl_->mesh; }
std::span<const double> HarmonicCoordinates::vertexValues() const { return impl_->values; }
double HarmonicCoordinates::meshVolumeBound() const { return impl_->volumeBound; }

TetLocator::Hit HarmonicCoordinates::locate(const Vec3& x) const {
  if (!isFinite(x)) throw InvalidInput("HarmonicCoordinates: the query point is not finite");
  return impl_->locator->locate(impl_->mesh.frame.toLocal(x));
}

void HarmonicCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  bool outside = false;
  impl_->rowAt(x, row, outside);
  if (outside && impl_->options.outside == HarmonicOutsidePolicy::Throw) {
    throw InvalidInput("HarmonicCoordinates: 1 point is outside the cage: " + pointText(x));
  }
}

std::shared_ptr<const Warp> HarmonicCoordinates::makeWarpFor(
    std::shared_ptr<const Coordinates> self, std::span<const Vec3> posed) const {
  return std::make_shared<HarmonicWarp>(
      std::static_pointer_cast<const HarmonicCoordinates>(std::move(self)), posed);
}

std::size_t HarmonicCoordinates::batchGrain() const { return kPointsPerTask; }

UnmappedPoints HarmonicCoordinates::weightsRange(std::span<const Vec3> points,
                                                 std::span<double> rows, std::size_t begin,
                                                 std::size_t end) const {
  const std::size_t m = columnCount();
  UnmappedPoints outside;
  for (std::size_t i = begin; i != end; ++i) {
    bool out = false;
    impl_->rowAt(points[i], rows.subspan(i * m, m), out);
    if (out && impl_->options.outside == HarmonicOutsidePolicy::Throw) outside.add(i);
  }
  return outside;
}

void HarmonicCoordinates::throwUnmapped(const UnmappedPoints& unmapped,
                                        std::span<const Vec3> points) const {
  throw InvalidInput("HarmonicCoordinates: " + std::to_string(unmapped.count) + " of " +
                     std::to_string(points.size()) +
                     " points are outside the cage (the first is point " +
                     std::to_string(unmapped.first) + " at " + pointText(points[unmapped.first]) +
                     "); " + detail::kNearestHint);
}

bool HarmonicCoordinates::weightGradients(const Vec3& x, std::span<Vec3> out) const {
  if (!isFinite(x)) throw InvalidInput("HarmonicCoordinates: the query point is not finite");
  if (out.size() != columnCount())
    throw InvalidInput("HarmonicCoordinates: the gradient output has the wrong size");
  const TetLocator::Hit hit = impl_->locator->locate(impl_->mesh.frame.toLocal(x));
  if (!hit.found) return false;
  auto g = impl_->locator->barycentricGradients(hit.tet);  // per frame unit
  for (Vec3& gradient : g) gradient /= impl_->mesh.frame.scale;
  const auto& tet = impl_->mesh.tets[hit.tet];
  const std::size_t n = impl_->k();
  for (std::size_t c = 0; c < n; ++c) {
    out[c] = impl_->values[tet[0] * n + c] * g[0] + impl_->values[tet[1] * n + c] * g[1] +
             impl_->values[tet[2] * n + c] * g[2] + impl_->values[tet[3] * n + c] * g[3];
  }
  return true;
}

// ---- files (the format: coords/detail/harmonic_file.h) ----

std::uint64_t HarmonicCoordinates::cageHash(const Cage& cage) {
  return detail::harmonicCageHash(cage);
}

HarmonicCoordinates::FileInfo HarmonicCoordinates::readFileInfo(const std::filesystem::path& path) {
  return detail::readHarmonicFileInfo(path);
}

void HarmonicCoordinates::save(const std::filesystem::path& path) const {
  const Impl& im = *impl_;
  detail::writeHarmonicFile(path, *im.cage, im.mesh, im.values, im.options.radiusEdgeRatio,
                            im.volumeBound);
}

std::shared_ptr<const HarmonicCoordinates> HarmonicCoordinates::load(
    const std::filesystem::path& path, std::shared_ptr<const Cage> cage,
    const HarmonicOptions& options) {
  if (!cage) throw InvalidInput("HarmonicCoordinates: the cage is null");
  checkOptions(options);
  // Read before the cage is moved into the state.
  detail::HarmonicFileData file = detail::readHarmonicFile(path, *cage);
  return std::shared_ptr<const HarmonicCoordinates>(new HarmonicCoordinates(
      FromImpl{}, implFromFile<Impl>(options, std::move(file), std::move(cage))));
}

void HarmonicCoordinates::save(ArchiveWriter& out) const {
  const Impl& im = *impl_;
  out.tag("harmonic");
  im.cage->save(out);
  out.u64(im.options.targetTetCount);
  out.f64(im.options.maxTetVolumeFraction);
  out.boolean(im.options.nonNegative);
  out.enumeration(im.options.outside);
  const std::vector<char> file = detail::encodeHarmonicFile(
      *im.cage, im.mesh, im.values, im.options.radiusEdgeRatio, im.volumeBound);
  out.string(std::string_view(file.data(), file.size()));
}

std::shared_ptr<const HarmonicCoordinates> HarmonicCoordinates::load(ArchiveReader& in) {
  auto cage = std::make_shared<const Cage>(Cage::load(in));
  HarmonicOptions options;
  options.targetTetCount = in.u64();
  options.maxTetVolumeFraction = in.f64();
  options.nonNegative = in.boolean();
  options.outside = in.enumeration<HarmonicOutsidePolicy>(2);
  const std::string bytes = in.string();
  detail::HarmonicFileData file;
  try {
    file = detail::decodeHarmonicFile(std::span<const char>(bytes.data(), bytes.size()), *cage,
                                      "harmonic coordinates");
  } catch (const IoError& e) {
    in.fail(e.what());  // a hostile archive is input, not a file that failed to read
  }
  options.radiusEdgeRatio = file.radiusEdgeRatio;
  checkOptions(options);
  return std::shared_ptr<const HarmonicCoordinates>(new HarmonicCoordinates(
      FromImpl{}, implFromFile<Impl>(options, std::move(file), std::move(cage))));
}

}  // namespace spacewarp
