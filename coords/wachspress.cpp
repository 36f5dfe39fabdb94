#include <spacewarp/coords/wachspress.h>

// Numerics
// ========
// For a point x inside the convex polyhedron, face g (outward unit normal n_g, offset d_g) is at
// height h_g = d_g − n_g · x > 0 and has the polar point p_g = n_g / h_g. Vertex v, whose faces
// g_1 … g_k (k ≥ 3) run counter-clockwise around it seen from outside, gets the volume of its
// polar cone (Warren, Schaefer, Hirani and Desbrun 2007; Floater 2014, §6), as a fan from g_1:
//     w_v = Σ_{i=2}^{k−1} det(p_{g_1}, p_{g_i}, p_{g_{i+1}})
//         = r_{g_1} Σ_{i=2}^{k−1} D_{v,i} r_{g_i} r_{g_{i+1}},   r_g = 1 / h_g,
// with D_{v,i} = det(n_{g_1}, n_{g_i}, n_{g_{i+1}}) > 0 precomputed; the row is w / Σ w. This is
// CGAL's Wachspress_coordinates_3 on a triangle mesh, whose coplanar triangles would repeat a
// normal and add zero terms: merging them (detail/convex_polyhedron.h) changes nothing but the
// work, and lets quads and larger planar faces in.
//
// Near face g, h_g → 0 and the weights of g's corners grow like r_g while the others stay
// bounded: the rounding of h_g (about ε × diagonal) changes the normalised weights by about
// ε × diagonal / h_g times their share of the others, O(h_g), so the row stays accurate to a few ε
// however close x comes; their limit is the 2D Wachspress coordinates of the face. Points within
// snapTolerance × diagonal of the surface get those directly (detail::faceCoordinates at the
// nearest surface point), and so do points outside under ConvexOutsidePolicy::NearestPoint.

#include <cmath>
#include <string>
#include <vector>

#include <spacewarp/coords/detail/convex_polyhedron.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

constexpr const char* kName = "WachspressCoordinates";

// The fan of every vertex's polar cone: pivot face, then (face, next face, determinant) terms.
struct Fans {
  std::vector<std::uint32_t> pivot, offsets, a, b;
  std::vector<double> det;
};

Fans buildFans(const detail::ConvexPolyhedron& poly) {
  Fans fans;
  fans.offsets.push_back(0);
  for (std::size_t v = 0; v + 1 < poly.ringOffsets.size(); ++v) {
    const std::uint32_t* ring = poly.ring.data() + poly.ringOffsets[v];
    const std::size_t k = poly.ringOffsets[v + 1] - poly.ringOffsets[v];
    fans.pivot.push_back(ring[0]);
    const Vec3 n1 = poly.faces[ring[0]].normal;
    for (std::size_t i = 1; i + 1 < k; ++i) {
      fans.a.push_back(ring[i]);
      fans.b.push_back(ring[i + 1]);
      fans.det.push_back(
          glm::dot(n1, glm::cross(poly.faces[ring[i]].normal, poly.faces[ring[i + 1]].normal)));
    }
    fans.offsets.push_back(static_cast<std::uint32_t>(fans.a.size()));
  }
  return fans;
}

void interiorRow(const void* data, const detail::ConvexPolyhedron&, const Vec3& x,
                 std::span<const double> heights, std::span<double> row) {
  const Fans& fans = *static_cast<const Fans*>(data);
  thread_local std::vector<double> r;
  r.resize(heights.size());
  for (std::size_t g = 0; g < heights.size(); ++g) r[g] = 1.0 / heights[g];
  double sum = 0.0;
  for (std::size_t v = 0; v < row.size(); ++v) {
    double w = 0.0;
    for (std::uint32_t t = fans.offsets[v]; t < fans.offsets[v + 1]; ++t)
      w += fans.det[t] * r[fans.a[t]] * r[fans.b[t]];
    row[v] = w * r[fans.pivot[v]];
    sum += row[v];
  }
  if (!(std::isfinite(sum) && sum > 0.0))
    throw SolverError(std::string(kName) + ": the weight sum vanishes at " + detail::pointText(x));
  for (double& w : row) w /= sum;
}

}  // namespace

struct WachspressCoordinates::Impl {
  std::shared_ptr<const Cage> cage;
  WachspressOptions options;
  detail::ConvexPolyhedron poly;
  Fans fans;
  double snapLength = 0.0;

  bool row(const Vec3& x, std::span<double> out) const {
    return detail::convexRow(poly, x, snapLength, options.outside, interiorRow, &fans, out);
  }
};

WachspressCoordinates::WachspressCoordinates(std::shared_ptr<const Cage> cage,
                                             const WachspressOptions& options) {
  if (!cage) throw InvalidInput(std::string(kName) + ": the cage is null");
  detail::checkSnapTolerance(kName, options.snapTolerance);
  auto impl = std::make_unique<Impl>();
  impl->poly = detail::buildConvexPolyhedron(*cage, kName, options.planarity);
  impl->fans = buildFans(impl->poly);
  impl->snapLength = options.snapTolerance * cage->diagonal();
  impl->cage = std::move(cage);
  impl->options = options;
  impl_ = std::move(impl);
}

WachspressCoordinates::~WachspressCoordinates() = default;

std::size_t WachspressCoordinates::controlPointCount() const { return impl_->poly.vertices.size(); }

std::span<const Vec3> WachspressCoordinates::restControlPoints() const {
  return impl_->cage->vertices();
}

const Cage& WachspressCoordinates::cage() const { return *impl_->cage; }
const WachspressOptions& WachspressCoordinates::options() const { return impl_->options; }

void WachspressCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  if (!impl_->row(x, row)) throw InvalidInput(detail::outsideMessage(kName, 1, 1, 0, x));
}

// With ∇r_g = r_g² n_g (as ∂h_g/∂x = −n_g): ∇w_v by the product rule over the fan terms, and
// ∇(w_v / W) = (∇w_v − φ_v ∇W) / W.
bool WachspressCoordinates::weightGradients(const Vec3& x, std::span<Vec3> out) const {
  if (!isFinite(x)) throw InvalidInput(std::string(kName) + ": the query point is not finite");
  if (out.size() != columnCount())
    throw InvalidInput(std::string(kName) + ": the gradient output has the wrong size");
  const detail::ConvexPolyhedron& poly = impl_->poly;
  const Fans& fans = impl_->fans;
  thread_local std::vector<double> r, w;
  thread_local std::vector<Vec3> dr;
  r.resize(poly.faces.size());
  dr.resize(poly.faces.size());
  w.resize(out.size());
  for (std::size_t g = 0; g < poly.faces.size(); ++g) {
    const double h = poly.faces[g].offset - glm::dot(poly.faces[g].normal, x);
    if (!(h > impl_->snapLength)) return false;
    r[g] = 1.0 / h;
    dr[g] = (r[g] * r[g]) * poly.faces[g].normal;
  }
  double sum = 0.0;
  Vec3 dsum(0.0);
  for (std::size_t v = 0; v < out.size(); ++v) {
    double s = 0.0;
    Vec3 ds(0.0);
    for (std::uint32_t t = fans.offsets[v]; t < fans.offsets[v + 1]; ++t) {
      const std::uint32_t a = fans.a[t], b = fans.b[t];
      s += fans.det[t] * r[a] * r[b];
      ds += fans.det[t] * (r[b] * dr[a] + r[a] * dr[b]);
    }
    const std::uint32_t pivot = fans.pivot[v];
    w[v] = r[pivot] * s;
    out[v] = s * dr[pivot] + r[pivot] * ds;
    sum += w[v];
    dsum += out[v];
  }
  for (std::size_t v = 0; v < out.size(); ++v) out[v] = (out[v] - (w[v] / sum) * dsum) / sum;
  return true;
}

UnmappedPoints WachspressCoordinates::weightsRange(std::span<const Vec3> points,
                                                   std::span<double> rows, std::size_t begin,
                                                   std::size_t end) const {
  const std::size_t m = columnCount();
  UnmappedPoints outside;
  for (std::size_t i = begin; i != end; ++i)
    if (!impl_->row(points[i], rows.subspan(i * m, m))) outside.add(i);
  return outside;
}

void WachspressCoordinates::throwUnmapped(const UnmappedPoints& unmapped,
                                          std::span<const Vec3> points) const {
  throw InvalidInput(detail::outsideMessage(kName, unmapped.count, points.size(), unmapped.first,
                                            points[unmapped.first]));
}

void WachspressCoordinates::save(ArchiveWriter& out) const {
  out.tag("wachspress");
  impl_->cage->save(out);
  out.f64(impl_->options.snapTolerance);
  out.enumeration(impl_->options.outside);
  out.f64(impl_->options.planarity);
}

std::shared_ptr<const WachspressCoordinates> WachspressCoordinates::load(ArchiveReader& in) {
  auto cage = std::make_shared<const Cage>(Cage::load(in));
  WachspressOptions options;
  options.snapTolerance = in.f64();
  options.outside = in.enumeration<ConvexOutsidePolicy>(2);
  options.planarity = in.f64();
  return std::make_shared<const WachspressCoordinates>(std::move(cage), options);
}

}  // namespace spacewarp
