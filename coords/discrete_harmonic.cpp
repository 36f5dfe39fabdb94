#include <spacewarp/coords/discrete_harmonic.h>

// Numerics
// ========
// CGAL's Discrete_harmonic_coordinates_3 gives the corner c of every cage triangle T = (a, b, c)
// the cotangent weight ½ |ab| cot θ_T, θ_T the dihedral angle at the edge ab between T and the
// plane through x and ab: the cotangent Laplacian of the tetrahedra that cone x over the faces
// (Ju, Liepa and Warren 2007). With h_T = d_T − n_T · x the height of x below T's plane and x₀ =
// x + h_T n_T its projection, cot θ_T = dist(x₀, line ab) / h_T (signed towards c), so
//     ½ |ab| cot θ_T = area(x₀, a, b) / h_T = (A_T / h_T) λ_c^T(x₀),
// A_T the area of T and λ^T(x₀) the barycentric coordinates of x₀ in T. Summed over faces,
//     w = Σ_F (A_F / h_F) φ^F(x₀,F),    row = w / Σ_F A_F / h_F,
// with φ^F linearly precise 2D coordinates of F: Σ_v w_v (p_v − x) = Σ_F A_F n_F = 0, which is
// linear precision. For triangles φ^F = λ^F, exactly CGAL's weights (which need a strictly convex
// triangle mesh). A planar polygon, or a group of coplanar cage faces merged into one
// (detail/convex_polyhedron.h), takes its 2D discrete harmonic coordinates as φ^F: then the
// weights do not depend on how a face is triangulated, and the row tends to the face's 2D
// discrete harmonic coordinates on it, as it does to barycentric ones on a triangle. (Summing
// CGAL's triangle terms over a triangulated quad instead would be an affine φ^F, which cannot
// interpolate the quad's four corners: the row would not be Lagrange on such a face.)
//
// Caveat: φ^F is evaluated at x₀, which lies outside F for some interior points of most
// polyhedra, and there the continued 2D coordinates of a polygon have poles (where their sum
// vanishes) unless the polygon is a triangle or a rectangle. No pole-free choice of φ^F can be
// Lagrange on a polygon and linearly precise (a pole-free φ^F · A_F / h_F that is affine in x₀ is
// what a triangulation gives, and an affine function cannot interpolate four corners); 3D
// discrete harmonic coordinates are defined for simplicial polytopes (CGAL takes strictly convex
// triangle meshes only), and this is the extension that keeps their face behaviour. Measured
// (20,000 interior points each): boxes, triangulated boxes, a hexagonal prism and a truncated
// octahedron keep every weight above −0.07; a sheared box (parallelograms) reaches −198, an affine
// image of the truncated octahedron −1199, a prism over trapezoids three times wider at the waist
// −4956; partition of unity and linear reproduction stay within 5e-13 in all of them. Cyclic
// faces (corners on one circle) use the equal Wachspress form, whose sum does not vanish on a
// rectangle. A point met exactly at a pole is a SolverError naming it and the face.
//
// Near face g, A_g / h_g grows and the row tends to φ^g (2D discrete harmonic coordinates), with
// the same absolute stability as the Wachspress row (see wachspress.cpp). Points within
// snapTolerance × diagonal of the surface, and outside points under NearestPoint, get the surface
// coordinates of the nearest surface point.

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
  thread_local std::vector<double> local;
  std::fill(row.begin(), row.end(), 0.0);
  const std::span<const Vec3> p = poly.vertices;
  for (std::size_t g = 0; g < poly.faces.size(); ++g) {
    const detail::ConvexPolyhedron::Face& face = poly.faces[g];
    const std::uint32_t* c = face.loop.data();
    if (face.loop.size() == 3) {  // A λ_c(x₀) = area(x₀, a, b), a and b the other two corners
      const Vec3 u = p[c[0]] - x, v = p[c[1]] - x, w = p[c[2]] - x;
      const double scale = 0.5 / heights[g];
      row[c[0]] += scale * glm::dot(face.normal, glm::cross(v, w));
      row[c[1]] += scale * glm::dot(face.normal, glm::cross(w, u));
      row[c[2]] += scale * glm::dot(face.normal, glm::cross(u, v));
      continue;
    }
    local.resize(face.loop.size());
    const Vec3 x0 = x + heights[g] * face.normal;
    if (!detail::faceCoordinates(face, p, x0, detail::FaceCoordinates::DiscreteHarmonic, local)) {
      throw SolverError(std::string(kName) + ": the point " + detail::pointText(x) +
                        " projects onto a pole of the 2D coordinates of face " +
                        std::to_string(face.source[0]) + " (not a cyclic polygon)");
    }
    const double scale = face.area / heights[g];
    for (std::size_t j = 0; j < face.loop.size(); ++j) row[c[j]] += scale * local[j];
  }
  double sum = 0.0;
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
    return detail::convexRow(poly, x, snapLength, options.outside,
                             detail::FaceCoordinates::DiscreteHarmonic, interiorRow, nullptr, out);
  }
};

DiscreteHarmonicCoordinates::DiscreteHarmonicCoordinates(std::shared_ptr<const Cage> cage,
                                                         const DiscreteHarmonicOptions& options) {
  if (!cage) throw InvalidInput(std::string(kName) + ": the cage is null");
  detail::checkSnapTolerance(kName, options.snapTolerance);
  auto impl = std::make_unique<Impl>();
  impl->poly = detail::buildConvexPolyhedron(*cage, kName);
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

// Per face, with ∇(1/h) = n / h²: a triangle's term area(x₀, a, b) / h = ½ n · ((a − x) × (b − x))
// / h has ∇ = ½ (n × (b − a) / h + 2 area n / h²); a polygon's (A / h) φ(x₀) has
// ∇ = A (φ n / h² + ∇φ(x₀) / h), ∇φ in the face's plane (x₀ moves with x's projection). Then
// ∇(w_v / W) = (∇w_v − φ_v ∇W) / W.
bool DiscreteHarmonicCoordinates::weightGradients(const Vec3& x, std::span<Vec3> out) const {
  if (!isFinite(x)) throw InvalidInput(std::string(kName) + ": the query point is not finite");
  if (out.size() != columnCount())
    throw InvalidInput(std::string(kName) + ": the gradient output has the wrong size");
  const detail::ConvexPolyhedron& poly = impl_->poly;
  const std::span<const Vec3> p = poly.vertices;
  std::vector<double> w(out.size(), 0.0), local;
  std::vector<Vec3> localGradients;
  std::fill(out.begin(), out.end(), Vec3(0.0));
  for (const detail::ConvexPolyhedron::Face& face : poly.faces) {
    const double h = face.offset - glm::dot(face.normal, x);
    if (!(h > impl_->snapLength)) return false;
    const Vec3 n = face.normal;
    const std::uint32_t* c = face.loop.data();
    const std::size_t m = face.loop.size();
    if (m == 3) {
      for (std::size_t k = 0; k < 3; ++k) {
        const Vec3 a = p[c[(k + 1) % 3]], b = p[c[(k + 2) % 3]];
        const double twiceArea = glm::dot(n, glm::cross(a - x, b - x));
        w[c[k]] += 0.5 * twiceArea / h;
        out[c[k]] += 0.5 * (glm::cross(n, b - a) / h + (twiceArea / (h * h)) * n);
      }
      continue;
    }
    local.resize(m);
    localGradients.resize(m);
    const Vec3 x0 = x + h * n;
    if (!detail::faceCoordinates(face, p, x0, detail::FaceCoordinates::DiscreteHarmonic, local) ||
        !detail::faceCoordinateGradients(face, p, x0, detail::FaceCoordinates::DiscreteHarmonic,
                                         localGradients)) {
      return false;
    }
    for (std::size_t j = 0; j < m; ++j) {
      w[c[j]] += face.area / h * local[j];
      out[c[j]] += face.area * ((local[j] / (h * h)) * n + localGradients[j] / h);
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
}

std::shared_ptr<const DiscreteHarmonicCoordinates> DiscreteHarmonicCoordinates::load(
    ArchiveReader& in) {
  auto cage = std::make_shared<const Cage>(Cage::load(in));
  DiscreteHarmonicOptions options;
  options.snapTolerance = in.f64();
  options.outside = in.enumeration<ConvexOutsidePolicy>(2);
  return std::make_shared<const DiscreteHarmonicCoordinates>(std::move(cage), options);
}

}  // namespace spacewarp
