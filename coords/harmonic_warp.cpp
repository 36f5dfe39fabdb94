#include <spacewarp/coords/harmonic_warp.h>

#include <algorithm>
#include <limits>
#include <string>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <spacewarp/coords/detail/outside_hint.h>
#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

HarmonicWarp::HarmonicWarp(std::shared_ptr<const HarmonicCoordinates> coordinates,
                           std::span<const Vec3> posed)
    : coordinates_(std::move(coordinates)), posed_(posed.begin(), posed.end()) {
  if (!coordinates_) throw InvalidInput("HarmonicWarp: the coordinates are null");
  const std::size_t k = coordinates_->controlPointCount();
  cageDisplacement_.resize(k);
  coordinates_->columnControls(posed, cageDisplacement_);  // checks size and finiteness
  for (std::size_t c = 0; c < k; ++c) cageDisplacement_[c] -= coordinates_->restControlPoints()[c];
  const std::span<const double> values = coordinates_->vertexValues();
  const std::size_t n = coordinates_->mesh().vertices.size();
  vertexDisplacement_.resize(n);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1024),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t v = r.begin(); v != r.end(); ++v) {
                        Vec3 d(0.0);
                        for (std::size_t c = 0; c < k; ++c)
                          d += values[v * k + c] * cageDisplacement_[c];
                        vertexDisplacement_[v] = d;
                      }
                    });
}

bool HarmonicWarp::displacement(const Vec3& x, Vec3& d) const {
  const TetLocator::Hit at = coordinates_->locate(x);
  if (at.found) {
    const auto& tet = coordinates_->mesh().tets[at.tet];
    d = at.barycentric[0] * vertexDisplacement_[tet[0]] +
        at.barycentric[1] * vertexDisplacement_[tet[1]] +
        at.barycentric[2] * vertexDisplacement_[tet[2]] +
        at.barycentric[3] * vertexDisplacement_[tet[3]];
    return true;
  }
  if (coordinates_->options().outside != HarmonicOutsidePolicy::NearestPoint) return false;
  std::vector<double> w(cageDisplacement_.size());
  coordinates_->weights(x, w);
  d = Vec3(0.0);
  for (std::size_t c = 0; c < w.size(); ++c) d += w[c] * cageDisplacement_[c];
  return true;
}

Vec3 HarmonicWarp::apply(const Vec3& x) const {
  if (!isFinite(x)) throw InvalidInput("HarmonicWarp: the point is not finite");
  Vec3 d;
  if (!displacement(x, d)) {
    throw InvalidInput("HarmonicWarp: 1 point is outside the cage: (" + std::to_string(x.x) + ", " +
                       std::to_string(x.y) + ", " + std::to_string(x.z) + ")");
  }
  return x + d;
}

std::size_t HarmonicWarp::batchGrain() const { return 1024; }

// Outside points are left where they are and counted; throwUnmapped() explains them.
UnmappedPoints HarmonicWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                        std::size_t begin, std::size_t end) const {
  UnmappedPoints outside;
  for (std::size_t i = begin; i != end; ++i) {
    const Vec3 x = in[i];
    Vec3 d;
    if (isFinite(x) && displacement(x, d)) {
      out[i] = x + d;
    } else {
      out[i] = x;
      outside.add(i);
    }
  }
  return outside;
}

void HarmonicWarp::throwUnmapped(const UnmappedPoints& unmapped, std::span<const Vec3> in) const {
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (!isFinite(in[i]))
      throw InvalidInput("HarmonicWarp: point " + std::to_string(i) + " is not finite");
  }
  throw InvalidInput("HarmonicWarp: " + std::to_string(unmapped.count) + " of " +
                     std::to_string(in.size()) +
                     " points are outside the cage (the first is point " +
                     std::to_string(unmapped.first) + "); " + detail::kNearestHint);
}

Mat3 HarmonicWarp::jacobian(const Vec3& x) const {
  if (!isFinite(x)) throw InvalidInput("HarmonicWarp: the point is not finite");
  const TetLocator::Hit at = coordinates_->locate(x);
  if (!at.found) {
    if (coordinates_->options().outside != HarmonicOutsidePolicy::NearestPoint)
      throw InvalidInput("HarmonicWarp: 1 point is outside the cage");
    return Warp::jacobian(x);
  }
  // In the cage's frame (accurate wherever the cage is), then per world unit.
  const TetMesh& mesh = coordinates_->mesh();
  const auto& tet = mesh.tets[at.tet];
  const std::vector<Vec3>& p = mesh.localVertices;
  const Mat3 inv =
      glm::inverse(Mat3(p[tet[1]] - p[tet[0]], p[tet[2]] - p[tet[0]], p[tet[3]] - p[tet[0]]));
  Vec3 g[4];
  for (int i = 0; i < 3; ++i) g[i + 1] = Vec3(inv[0][i], inv[1][i], inv[2][i]) / mesh.frame.scale;
  g[0] = -(g[1] + g[2] + g[3]);
  Mat3 j(1.0);
  for (int a = 0; a < 4; ++a)
    for (int c = 0; c < 3; ++c)
      j[c] += vertexDisplacement_[tet[static_cast<std::size_t>(a)]] * g[a][c];
  return j;
}

void HarmonicWarp::save(ArchiveWriter& out) const {
  out.tag("harmonic-warp");
  out.coordinates(*coordinates_);
  out.vec3s(posed_);
}

std::shared_ptr<const HarmonicWarp> HarmonicWarp::load(ArchiveReader& in) {
  auto coordinates = std::dynamic_pointer_cast<const HarmonicCoordinates>(in.coordinates());
  if (!coordinates) in.fail("a harmonic warp's coordinates are not harmonic coordinates");
  const std::vector<Vec3> posed = in.vec3s();
  return std::make_shared<const HarmonicWarp>(std::move(coordinates), posed);
}

}  // namespace spacewarp
