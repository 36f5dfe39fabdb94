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
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <Eigen/Cholesky>
#include <Eigen/CholmodSupport>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <spacewarp/coords/tet_locator.h>
#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/detail/serial_blas.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>

namespace spacewarp {

namespace {

static_assert(std::endian::native == std::endian::little,
              "the harmonic coordinate file format is little-endian");

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

constexpr char kMagic[8] = {'S', 'W', 'H', 'A', 'R', 'M', 'C', '\0'};
// Version 2: the mesh vertices are stored in the cage's frame (version 1 stored them in world
// units and is still read).
constexpr std::uint32_t kVersion = 2;
constexpr std::size_t kHeaderSize = 72;

using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

// FNV-1a, 64-bit, over bytes.
struct Fnv {
  std::uint64_t h = 0xcbf29ce484222325ull;
  void add(const void* data, std::size_t size) {
    const auto* p = static_cast<const unsigned char*>(data);
    std::uint64_t x = h;
    for (std::size_t i = 0; i < size; ++i) x = (x ^ p[i]) * 0x100000001b3ull;
    h = x;
  }
};

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
      const double phiNext = evaluate(next, nullptr, nullptr);
      if (phiNext <= phi + 1e-4 * t * slope) {
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

double HarmonicCoordinates::memoryEstimate(const Cage& cage, const HarmonicOptions& options) {
  const double tets = expectedTets(cage, tetVolumeBound(cage, options));
  const double k = static_cast<double>(cage.vertexCount());
  return kBytesPerCageTriangle * static_cast<double>(cage.triangleCount()) +
         (kBytesPerTet - kSolveBytesPerTet) * tets + solveBytes(tets, tets / 4.0 + k, k);
}

double HarmonicCoordinates::tetVolumeBound(const Cage& cage, const HarmonicOptions& options) {
  if (options.maxTetVolume > 0.0) return options.maxTetVolume * cage.volume();
  return cage.volume() / (kMeanVolumeFraction * static_cast<double>(options.targetTetCount));
}

namespace {

void checkOptions(const HarmonicOptions& options) {
  if (options.targetTetCount < 1)
    throw InvalidInput("HarmonicCoordinates: targetTetCount must be >= 1");
  if (!(std::isfinite(options.maxTetVolume) && options.maxTetVolume >= 0.0 &&
        options.maxTetVolume <= 1.0)) {
    throw InvalidInput(
        "HarmonicCoordinates: maxTetVolume must be in [0, 1] (relative to the cage "
        "volume), got " +
        number(options.maxTetVolume));
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

// Solves for the coordinate values at every mesh vertex (n × k, row-major).
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

  // Assembly of K_II (lower triangle) and the right-hand sides −K_IB U_B.
  ProgressTracker factorise(progress, "factorise", 2);
  std::vector<Eigen::Triplet<double, int>> triplets;
  triplets.reserve(mesh.tets.size() * 10);
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nI, static_cast<Eigen::Index>(k));
  const std::vector<Vec3>& p = mesh.localVertices;
  for (const auto& tet : mesh.tets) {
    const Mat3 d(p[tet[1]] - p[tet[0]], p[tet[2]] - p[tet[0]], p[tet[3]] - p[tet[0]]);
    const double det = glm::determinant(d);
    if (!(det > 0.0)) continue;  // a flat tet adds nothing
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
        for (std::size_t j = 0; j < count; ++j) rhs(ia, bv[j].first) -= kab * bv[j].second;
      }
    }
  }
  SparseMatrix a(nI, nI);
  a.setFromTriplets(triplets.begin(), triplets.end());
  triplets = {};
  factorise.advance();
  // CHOLMOD's supernodal Cholesky (BLAS-3 on the dense supernodes): on the armadillo cage at
  // ~190k tets (21k interior vertices) it factorises in 0.7 s and solves the 110 right-hand
  // sides in 0.2 s, where Eigen's simplicial LDLᵀ took 1.4 s and 1.9 s (one thread; 1 s with
  // the columns spread over two threads).
  // A single-threaded BLAS for the factorisation and the solves: bit-identical results for
  // any OPENBLAS_NUM_THREADS.
  const detail::SerialBlas serialBlas;
  Eigen::CholmodSupernodalLLT<SparseMatrix, Eigen::Lower> llt;
  // Eigen's wrapper does not look at CHOLMOD's status: an analysis that ran out of memory
  // leaves no factor (which factorize() would dereference), and a factorisation that did still
  // reports success.
  const auto requireMemory = [&](const char* step) {
    if (llt.cholmod().status == CHOLMOD_OUT_OF_MEMORY)
      throw OutOfMemory("HarmonicCoordinates: the sparse Cholesky " + std::string(step) +
                        " of the Laplacian of " + std::to_string(nI) +
                        " interior vertices ran out of memory");
  };
  llt.analyzePattern(a);
  requireMemory("analysis");
  if (llt.cholmod().status < CHOLMOD_OK) {
    throw SolverError("HarmonicCoordinates: the analysis of the Laplacian of " +
                      std::to_string(nI) + " interior vertices failed");
  }
  llt.factorize(a);
  requireMemory("factorisation");
  if (llt.info() != Eigen::Success) {
    throw SolverError("HarmonicCoordinates: the factorisation of the Laplacian of " +
                      std::to_string(nI) + " interior vertices failed");
  }
  factorise.finish();

  // Blocks of kBlock columns, one after the other: every block is a BLAS-3 solve, and the
  // fixed blocks keep the result independent of any thread count.
  const std::size_t blocks = (k + kBlock - 1) / kBlock;
  ProgressTracker solve(progress, "solve", blocks);
  Eigen::MatrixXd x(nI, static_cast<Eigen::Index>(k));
  for (std::size_t blk = 0; blk < blocks; ++blk) {
    const auto c0 = static_cast<Eigen::Index>(blk * kBlock);
    const auto cols = static_cast<Eigen::Index>(std::min(kBlock, k - blk * kBlock));
    const Eigen::MatrixXd part = rhs.middleCols(c0, cols);
    x.middleCols(c0, cols) = llt.solve(part);
    if (llt.info() != Eigen::Success) {
      requireMemory("solve");
      throw SolverError("HarmonicCoordinates: the solve for the coordinate functions failed");
    }
    solve.advance();
  }
  for (std::size_t v = 0; v < n; ++v) {
    if (interior[v] < 0) continue;
    for (std::size_t c = 0; c < k; ++c)
      values[v * k + c] = x(interior[v], static_cast<Eigen::Index>(c));
  }
  if (nonNegative) {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 1024), [&](const tbb::blocked_range<std::size_t>& r) {
          for (std::size_t v = r.begin(); v != r.end(); ++v) {
            const std::span<double> row(values.data() + v * k, k);
            if (*std::min_element(row.begin(), row.end()) < 0.0)
              projectNonNegative(row, std::span(mesh.localVertices.data(), k),
                                 mesh.localVertices[v], cage.diagonal() / mesh.frame.scale);
          }
        });
  }
  solve.finish();
  return values;
}

// The point locator, in the cage's frame. Its slack is the round-off of a query point's world
// coordinates (a few ulps of the largest), in frame units: points on the cage surface far from
// the origin are on it only to that precision, which can exceed the relative tolerance.
std::unique_ptr<TetLocator> makeLocator(const TetMesh& mesh) {
  const double reach = maxAbs(mesh.frame.centre) + mesh.frame.scale;
  const double slack = 16.0 * std::numeric_limits<double>::epsilon() * reach / mesh.frame.scale;
  return std::make_unique<TetLocator>(mesh.localVertices, mesh.tets, 1e-10, slack);
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

HarmonicCoordinates::Location HarmonicCoordinates::locate(const Vec3& x) const {
  if (!isFinite(x)) throw InvalidInput("HarmonicCoordinates: the query point is not finite");
  const TetLocator::Hit hit = impl_->locator->locate(impl_->mesh.frame.toLocal(x));
  return {hit.found, hit.tet, hit.barycentric};
}

void HarmonicCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  bool outside = false;
  impl_->rowAt(x, row, outside);
  if (outside && impl_->options.outside == HarmonicOutsidePolicy::Throw) {
    throw InvalidInput("HarmonicCoordinates: 1 point is outside the cage: " + pointText(x));
  }
}

void HarmonicCoordinates::weightsBatch(std::span<const Vec3> points, std::span<double> rows) const {
  const std::size_t m = columnCount();
  if (rows.size() != points.size() * m) {
    throw InvalidInput("HarmonicCoordinates: " + std::to_string(points.size()) + " points need " +
                       std::to_string(points.size() * m) + " weights but the output has " +
                       std::to_string(rows.size()));
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!isFinite(points[i]))
      throw InvalidInput("HarmonicCoordinates: point " + std::to_string(i) + " is not finite");
  }
  // (count, first index) of the outside points.
  using Outside = std::pair<std::size_t, std::size_t>;
  const Outside none{0, std::numeric_limits<std::size_t>::max()};
  const Outside outside = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, points.size(), kPointsPerTask), none,
      [&](const tbb::blocked_range<std::size_t>& r, Outside acc) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
          bool out = false;
          impl_->rowAt(points[i], rows.subspan(i * m, m), out);
          if (out) acc = {acc.first + 1, std::min(acc.second, i)};
        }
        return acc;
      },
      [](const Outside& a, const Outside& b) {
        return Outside{a.first + b.first, std::min(a.second, b.second)};
      });
  if (outside.first > 0 && impl_->options.outside == HarmonicOutsidePolicy::Throw) {
    throw InvalidInput(
        "HarmonicCoordinates: " + std::to_string(outside.first) + " of " +
        std::to_string(points.size()) + " points are outside the cage (the first is point " +
        std::to_string(outside.second) + " at " + pointText(points[outside.second]) + ")");
  }
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

// ---- files ----

std::uint64_t HarmonicCoordinates::cageHash(const Cage& cage) {
  Fnv fnv;
  for (const Vec3& p : cage.vertices()) {
    const double xyz[3] = {p.x, p.y, p.z};
    fnv.add(xyz, sizeof xyz);
  }
  for (const Triangle& t : cage.triangles()) {
    const std::uint32_t abc[3] = {t.x, t.y, t.z};
    fnv.add(abc, sizeof abc);
  }
  return fnv.h;
}

namespace {

// Writes raw values into a buffer sized in advance.
struct Writer {
  char* at;
  void bytes(const void* data, std::size_t size) {
    std::memcpy(at, data, size);
    at += size;
  }
  template <typename T>
  void put(const T& value) {
    bytes(&value, sizeof(T));
  }
};

template <typename T>
T get(const std::vector<char>& in, std::size_t offset) {
  T value;
  std::memcpy(&value, in.data() + offset, sizeof(T));
  return value;
}

std::vector<char> readAll(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path.string() + ": cannot open the harmonic coordinate file");
  std::vector<char> data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw IoError(path.string() + ": cannot read the harmonic coordinate file");
  return data;
}

HarmonicCoordinates::FileInfo parseHeader(const std::vector<char>& data,
                                          const std::filesystem::path& path) {
  const std::string where = path.string() + ": ";
  if (data.size() < kHeaderSize + 8) {
    throw IoError(where + "not a harmonic coordinate file: " + std::to_string(data.size()) +
                  " bytes, too short for the header");
  }
  if (std::memcmp(data.data(), kMagic, sizeof kMagic) != 0)
    throw IoError(where + "not a harmonic coordinate file (bad magic)");
  HarmonicCoordinates::FileInfo info;
  info.version = get<std::uint32_t>(data, 8);
  if (info.version != 1 && info.version != kVersion) {
    throw IoError(where + "unsupported harmonic coordinate file version " +
                  std::to_string(info.version) + " (this build reads versions 1 and " +
                  std::to_string(kVersion) + ")");
  }
  info.cageVertexCount = get<std::uint64_t>(data, 16);
  info.cageTriangleCount = get<std::uint64_t>(data, 24);
  info.cageHash = get<std::uint64_t>(data, 32);
  info.meshVertexCount = get<std::uint64_t>(data, 40);
  info.tetCount = get<std::uint64_t>(data, 48);
  info.radiusEdgeRatio = get<double>(data, 56);
  info.maxTetVolume = get<double>(data, 64);
  return info;
}

}  // namespace

HarmonicCoordinates::FileInfo HarmonicCoordinates::readFileInfo(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path.string() + ": cannot open the harmonic coordinate file");
  std::vector<char> header(kHeaderSize + 8);
  in.read(header.data(), static_cast<std::streamsize>(header.size()));
  header.resize(static_cast<std::size_t>(in.gcount()));
  return parseHeader(header, path);
}

void HarmonicCoordinates::save(const std::filesystem::path& path) const {
  const Impl& im = *impl_;
  const std::size_t n = im.mesh.vertices.size(), k = im.k();
  const std::size_t size = kHeaderSize + n * (24 + 4 + 8 * k) + im.mesh.tets.size() * 16 + 8;
  std::vector<char> data(size);
  Writer w{data.data()};
  w.bytes(kMagic, sizeof kMagic);
  w.put(kVersion);
  w.put(std::uint32_t{0});
  w.put(static_cast<std::uint64_t>(k));
  w.put(static_cast<std::uint64_t>(im.cage->triangleCount()));
  w.put(cageHash(*im.cage));
  w.put(static_cast<std::uint64_t>(n));
  w.put(static_cast<std::uint64_t>(im.mesh.tets.size()));
  w.put(im.options.radiusEdgeRatio);
  w.put(im.volumeBound);
  for (const Vec3& p : im.mesh.localVertices) {
    w.put(p.x);
    w.put(p.y);
    w.put(p.z);
  }
  for (const auto& tet : im.mesh.tets)
    for (const std::uint32_t v : tet) w.put(v);
  for (const std::int32_t b : im.mesh.boundaryTriangle) w.put(b);
  w.bytes(im.values.data(), im.values.size() * sizeof(double));
  Fnv fnv;
  fnv.add(data.data(), size - 8);
  w.put(fnv.h);
  writeFileAtomically(path, [&](std::ostream& out) {
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
  });
}

std::shared_ptr<const HarmonicCoordinates> HarmonicCoordinates::load(
    const std::filesystem::path& path, std::shared_ptr<const Cage> cage,
    const HarmonicOptions& options) {
  if (!cage) throw InvalidInput("HarmonicCoordinates: the cage is null");
  checkOptions(options);
  const std::string where = path.string() + ": ";
  const std::vector<char> data = readAll(path);
  const FileInfo info = parseHeader(data, path);
  if (info.cageVertexCount != cage->vertexCount() ||
      info.cageTriangleCount != cage->triangleCount() || info.cageHash != cageHash(*cage)) {
    throw InvalidInput(where + "the harmonic coordinates were solved for another cage (" +
                       std::to_string(info.cageVertexCount) + " vertices, " +
                       std::to_string(info.cageTriangleCount) + " triangles; this cage has " +
                       std::to_string(cage->vertexCount()) + " and " +
                       std::to_string(cage->triangleCount()) +
                       (info.cageVertexCount == cage->vertexCount() &&
                                info.cageTriangleCount == cage->triangleCount()
                            ? ", but its vertices or triangles differ)"
                            : ")"));
  }
  const std::uint64_t n = info.meshVertexCount, m = info.tetCount, k = info.cageVertexCount;
  constexpr std::uint64_t kLimit = std::uint64_t{1} << 40;
  if (n < k || n > kLimit || m == 0 || m > kLimit || k > (kLimit / n)) {
    throw IoError(where + "corrupt harmonic coordinate file: impossible counts (" +
                  std::to_string(n) + " mesh vertices, " + std::to_string(m) + " tets)");
  }
  const std::uint64_t expected = kHeaderSize + n * 24 + m * 16 + n * 4 + n * k * 8 + 8;
  if (data.size() < expected) {
    throw IoError(where + "truncated harmonic coordinate file: " + std::to_string(data.size()) +
                  " bytes, " + std::to_string(expected) + " expected");
  }
  if (data.size() > expected) {
    throw IoError(where + "corrupt harmonic coordinate file: " +
                  std::to_string(data.size() - expected) + " trailing bytes");
  }
  Fnv fnv;
  fnv.add(data.data(), data.size() - 8);
  if (fnv.h != get<std::uint64_t>(data, data.size() - 8))
    throw IoError(where + "corrupt harmonic coordinate file: checksum mismatch");

  auto impl = std::make_unique<Impl>();
  impl->options = options;
  impl->options.radiusEdgeRatio = info.radiusEdgeRatio;
  impl->volumeBound = info.maxTetVolume;
  std::size_t offset = kHeaderSize;
  TetMesh& mesh = impl->mesh;
  mesh.frame = cage->frame();
  // Version 2 stores the vertices in the cage's frame, version 1 in world units.
  std::vector<Vec3>& stored = info.version == 1 ? mesh.vertices : mesh.localVertices;
  stored.resize(n);
  for (Vec3& p : stored) {
    p = Vec3(get<double>(data, offset), get<double>(data, offset + 8),
             get<double>(data, offset + 16));
    offset += 24;
    if (!isFinite(p))
      throw IoError(where + "corrupt harmonic coordinate file: a vertex is not finite");
  }
  for (std::size_t i = 0; i < k; ++i) {
    if (info.version == 1 ? stored[i] != cage->vertices()[i]
                          : stored[i] != mesh.frame.toLocal(cage->vertices()[i])) {
      throw IoError(where + "corrupt harmonic coordinate file: mesh vertex " + std::to_string(i) +
                    " is not cage vertex " + std::to_string(i));
    }
  }
  if (info.version == 1) {
    mesh.localVertices.resize(n);
    for (std::size_t i = 0; i < n; ++i)
      mesh.localVertices[i] = mesh.frame.toLocal(mesh.vertices[i]);
  } else {
    mesh.vertices = worldVertices(*cage, mesh.frame, mesh.localVertices);
  }
  mesh.tets.resize(m);
  for (auto& tet : mesh.tets) {
    for (std::uint32_t& v : tet) {
      v = get<std::uint32_t>(data, offset);
      offset += 4;
      if (v >= n)
        throw IoError(where + "corrupt harmonic coordinate file: a tet corner is out of range");
    }
  }
  mesh.boundaryTriangle.resize(n);
  for (std::int32_t& b : mesh.boundaryTriangle) {
    b = get<std::int32_t>(data, offset);
    offset += 4;
    if (b < -1 || (b >= 0 && static_cast<std::uint64_t>(b) >= info.cageTriangleCount))
      throw IoError(where +
                    "corrupt harmonic coordinate file: a boundary triangle is out of range");
  }
  impl->values.resize(n * k);
  std::memcpy(impl->values.data(), data.data() + offset, n * k * sizeof(double));
  for (const double v : impl->values) {
    if (!std::isfinite(v))
      throw IoError(where + "corrupt harmonic coordinate file: a coordinate value is not finite");
  }
  impl->cage = std::move(cage);
  return std::shared_ptr<const HarmonicCoordinates>(
      new HarmonicCoordinates(FromImpl{}, std::move(impl)));
}

}  // namespace spacewarp
