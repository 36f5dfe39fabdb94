#include <spacewarp/coords/discrete_harmonic.h>

// Numerics
// ========
// CGAL's Discrete_harmonic_coordinates_3 gives the corner c of every cage triangle T = (a, b, c)
// the cotangent weight ½ |ab| cot θ_T, θ_T the dihedral angle at the edge ab between T and the
// plane through x and ab: the cotangent Laplacian of the tetrahedra that cone x over the faces
// (Ju, Liepa and Warren 2007). With h_T = d_T − n_T · x the height of x below T's plane and x₀ =
// x + h_T n_T its projection, cot θ_T = dist(x₀, line ab) / h_T (signed towards c), so
//     ½ |ab| cot θ_T = area(x₀, a, b) / h_T = ½ n_T · ((a − x) × (b − x)) / h_T,
// and row = w / Σ_T A_T / h_T (the weights of a triangle sum to its area A_T over h_T). Linear
// precision: Σ_v w_v (p_v − x) = Σ_T A_T n_T = 0.
//
// Simplicial polytopes only, as CGAL: every face of the polyhedron, after merging coplanar
// neighbours (detail/convex_polyhedron.h), must be a triangle. The generalisation to a polygon
// face F, (A_F / h_F) φ^F(x₀) with φ^F its 2D discrete harmonic coordinates, evaluates φ^F at x₀,
// which leaves F for interior points of most polyhedra, where the continued φ^F has poles: weights
// of −198 (sheared box), −1199 (affine truncated octahedron) and −4956 (box wider at the waist)
// were measured at interior points. Summing the triangle terms of a triangulation of F instead is
// affine in x₀ and cannot interpolate F's corners: the row would not be Lagrange there, and would
// jump at them. Wachspress coordinates take polygon faces.
//
// Weight range: see discrete_harmonic.h (measured on simplicial cages; at most −0.36 on random
// hulls; the polygon-face continuation reached −4956). A weight is negative only where x
// sees a triangle's dihedral angle above 90° (a negative cotangent); nothing bounds it for
// arbitrarily thin triangles, so the bound is a measurement, not a theorem.
//
// Near face T, A_T / h_T grows and the row tends to the barycentric coordinates of x₀ in T, with
// the same absolute stability as the Wachspress row (see wachspress.cpp). Points within
// snapTolerance × diagonal of the surface, and outside points under NearestPoint, get the
// barycentric coordinates of the nearest surface point.

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <spacewarp/coords/detail/convex_polyhedron.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

constexpr const char* kName = "DiscreteHarmonicCoordinates";

void interiorRow(const void*, const detail::ConvexPolyhedron& poly, const Vec3& x,
                 std::span<const double> heights, std::span<double> row) {
  std::fill(row.begin(), row.end(), 0.0);
  const std::span<const Vec3> p = poly.vertices;
  for (std::size_t g = 0; g < poly.faces.size(); ++g) {
    const detail::ConvexPolyhedron::Face& face = poly.faces[g];
    const std::uint32_t* c = face.loop.data();
    const Vec3 u = p[c[0]] - x, v = p[c[1]] - x, w = p[c[2]] - x;
    const double scale = 0.5 / heights[g];
    row[c[0]] += scale * glm::dot(face.normal, glm::cross(v, w));
    row[c[1]] += scale * glm::dot(face.normal, glm::cross(w, u));
    row[c[2]] += scale * glm::dot(face.normal, glm::cross(u, v));
  }
  double sum = 0.0;  // Σ_T A_T / h_T, summed from the row so that it sums to 1 to round-off
  for (double w : row) sum += w;
  if (!(std::isfinite(sum) && sum > 0.0))
    throw SolverError(std::string(kName) + ": the weight sum vanishes at " + detail::pointText(x));
  for (double& w : row) w /= sum;
}

}  // namespace

struct DiscreteHarmonicCoordinates::Impl {
  std::shared_ptr<const Cage> cage;
  DiscreteHarmonicOptions options;
  detail::ConvexPolyhedron poly;
  double snapLength = 0.0;

  bool row(const Vec3& x, std::span<double> out) const {
    return detail::convexRow(poly, x, snapLength, options.outside, interiorRow, nullptr, out);
  }
};

DiscreteHarmonicCoordinates::DiscreteHarmonicCoordinates(std::shared_ptr<const Cage> cage,
                                                         const DiscreteHarmonicOptions& options) {
  if (!cage) throw InvalidInput(std::string(kName) + ": the cage is null");
  detail::checkSnapTolerance(kName, options.snapTolerance);
  auto impl = std::make_unique<Impl>();
  impl->poly = detail::buildConvexPolyhedron(*cage, kName, options.planarity);
  detail::checkSimplicial(impl->poly, *cage, kName);
  impl->snapLength = options.snapTolerance * cage->diagonal();
  impl->cage = std::move(cage);
  impl->options = options;
  impl_ = std::move(impl);
}

DiscreteHarmonicCoordinates::~DiscreteHarmonicCoordinates() = default;

std::size_t DiscreteHarmonicCoordinates::controlPointCount() const {
  return impl_->poly.vertices.size();
}

std::span<const Vec3> DiscreteHarmonicCoordinates::restControlPoints() const {
  return impl_->cage->vertices();
}

const Cage& DiscreteHarmonicCoordinates::cage() const { return *impl_->cage; }
const DiscreteHarmonicOptions& DiscreteHarmonicCoordinates::options() const {
  return impl_->options;
}

void DiscreteHarmonicCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  if (!impl_->row(x, row)) throw InvalidInput(detail::outsideMessage(kName, 1, 1, 0, x));
}

// Per triangle, with ∇(1/h) = n / h²: the term area(x₀, a, b) / h = ½ n · ((a − x) × (b − x)) / h
// of corner c has ∇ = ½ (n × (b − a) / h + 2 area n / h²). Then ∇(w_v / W) = (∇w_v − φ_v ∇W) / W.
bool DiscreteHarmonicCoordinates::weightGradients(const Vec3& x, std::span<Vec3> out) const {
  if (!isFinite(x)) throw InvalidInput(std::string(kName) + ": the query point is not finite");
  if (out.size() != columnCount())
    throw InvalidInput(std::string(kName) + ": the gradient output has the wrong size");
  const detail::ConvexPolyhedron& poly = impl_->poly;
  const std::span<const Vec3> p = poly.vertices;
  std::vector<double> w(out.size(), 0.0);
  std::fill(out.begin(), out.end(), Vec3(0.0));
  for (const detail::ConvexPolyhedron::Face& face : poly.faces) {
    const double h = face.offset - glm::dot(face.normal, x);
    if (!(h > impl_->snapLength)) return false;
    const Vec3 n = face.normal;
    const std::uint32_t* c = face.loop.data();
    for (std::size_t k = 0; k < 3; ++k) {
      const Vec3 a = p[c[(k + 1) % 3]], b = p[c[(k + 2) % 3]];
      const double twiceArea = glm::dot(n, glm::cross(a - x, b - x));
      w[c[k]] += 0.5 * twiceArea / h;
      out[c[k]] += 0.5 * (glm::cross(n, b - a) / h + (twiceArea / (h * h)) * n);
    }
  }
  double sum = 0.0;
  Vec3 dsum(0.0);
  for (std::size_t v = 0; v < out.size(); ++v) {
    sum += w[v];
    dsum += out[v];
  }
  for (std::size_t v = 0; v < out.size(); ++v) out[v] = (out[v] - (w[v] / sum) * dsum) / sum;
  return true;
}

UnmappedPoints DiscreteHarmonicCoordinates::weightsRange(std::span<const Vec3> points,
                                                         std::span<double> rows, std::size_t begin,
                                                         std::size_t end) const {
  const std::size_t m = columnCount();
  UnmappedPoints outside;
  for (std::size_t i = begin; i != end; ++i)
    if (!impl_->row(points[i], rows.subspan(i * m, m))) outside.add(i);
  return outside;
}

void DiscreteHarmonicCoordinates::throwUnmapped(const UnmappedPoints& unmapped,
                                                std::span<const Vec3> points) const {
  throw InvalidInput(detail::outsideMessage(kName, unmapped.count, points.size(), unmapped.first,
                                            points[unmapped.first]));
}

void DiscreteHarmonicCoordinates::save(ArchiveWriter& out) const {
  out.tag("discrete-harmonic");
  impl_->cage->save(out);
  out.f64(impl_->options.snapTolerance);
  out.enumeration(impl_->options.outside);
  out.f64(impl_->options.planarity);
}

std::shared_ptr<const DiscreteHarmonicCoordinates> DiscreteHarmonicCoordinates::load(
    ArchiveReader& in) {
  auto cage = std::make_shared<const Cage>(Cage::load(in));
  DiscreteHarmonicOptions options;
  options.snapTolerance = in.f64();
  options.outside = in.enumeration<ConvexOutsidePolicy>(2);
  options.planarity = in.f64();
  return std::make_shared<const DiscreteHarmonicCoordinates>(std::move(cage), options);
}

}  // namespace spacewarp
