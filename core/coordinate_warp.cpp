#include <spacewarp/core/coordinate_warp.h>

#include <string>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

CoordinateWarp::CoordinateWarp(std::shared_ptr<const Coordinates> coordinates,
                               std::span<const Vec3> posed)
    : coordinates_(std::move(coordinates)), posed_(posed.begin(), posed.end()) {
  if (!coordinates_) throw InvalidInput("CoordinateWarp: the coordinates are null");
  const std::size_t m = coordinates_->columnCount();
  std::vector<Vec3> rest(m);
  displacement_.resize(m);
  coordinates_->columnControls(coordinates_->restControlPoints(), rest);
  coordinates_->columnControls(posed, displacement_);
  for (std::size_t c = 0; c < m; ++c) displacement_[c] -= rest[c];
  sparse_ = 4 * coordinates_->maxNonZeros() <= m;
}

namespace {

Vec3 displace(const Vec3& x, std::span<const double> w, std::span<const Vec3> displacement) {
  Vec3 sum(0.0);
  for (std::size_t c = 0; c < w.size(); ++c) sum += w[c] * displacement[c];
  return x + sum;
}

}  // namespace

Vec3 CoordinateWarp::displaceSparse(const Vec3& x, std::span<SparseWeight> slots) const {
  const std::size_t count = coordinates_->sparseWeights(x, slots);
  Vec3 sum(0.0);
  for (std::size_t s = 0; s < count; ++s) sum += slots[s].weight * displacement_[slots[s].column];
  return x + sum;
}

Vec3 CoordinateWarp::apply(const Vec3& x) const {
  if (sparse_) {
    std::vector<SparseWeight> slots(coordinates_->maxNonZeros());
    return displaceSparse(x, slots);
  }
  std::vector<double> w(displacement_.size());
  coordinates_->weights(x, w);
  return displace(x, w, displacement_);
}

UnmappedPoints CoordinateWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                          std::size_t begin, std::size_t end) const {
  if (sparse_) {
    std::vector<SparseWeight> slots(coordinates_->maxNonZeros());
    for (std::size_t i = begin; i != end; ++i) out[i] = displaceSparse(in[i], slots);
    return {};
  }
  const std::size_t m = displacement_.size();
  std::vector<double> rows((end - begin) * m);
  coordinates_->weightsBatch(in, begin, end, rows);  // errors name the caller's indices
  // `in` and `out` may alias: each point is read just before its own slot is written.
  for (std::size_t i = begin; i != end; ++i) {
    const Vec3 x = in[i];
    out[i] = displace(x, std::span(rows).subspan((i - begin) * m, m), displacement_);
  }
  return {};
}

Mat3 CoordinateWarp::jacobian(const Vec3& x) const {
  std::vector<Vec3> gradients(displacement_.size());
  if (!coordinates_->weightGradients(x, gradients)) return Warp::jacobian(x);
  Mat3 j(1.0);
  // J += d ∇wᵀ: column k of the outer product is d * (∇w)_k.
  for (std::size_t c = 0; c < gradients.size(); ++c)
    for (int k = 0; k < 3; ++k) j[k] += displacement_[c] * gradients[c][k];
  return j;
}

void CoordinateWarp::save(ArchiveWriter& out) const {
  out.tag("coordinate-warp");
  out.coordinates(*coordinates_);
  out.vec3s(posed_);
}

std::shared_ptr<const CoordinateWarp> CoordinateWarp::load(ArchiveReader& in) {
  std::shared_ptr<const Coordinates> coordinates = in.coordinates();
  const std::vector<Vec3> posed = in.vec3s();
  return std::make_shared<const CoordinateWarp>(std::move(coordinates), posed);
}

}  // namespace spacewarp
