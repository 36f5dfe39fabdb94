#include <spacewarp/nonlinear/detail/chord_tree.h>

#include <algorithm>

namespace spacewarp::detail {

namespace {

// Pruning slack: a box is skipped only when it is farther than the best chord by more than the
// rounding of the two computed distances (boxes grown by kMarginOfScale of the coordinates, and
// a relative slack for far points), so the result is that of checking every chord.
constexpr double kMarginOfScale = 1e-10;
constexpr double kSlack = 1.0 + 1e-9;

}  // namespace

ChordTree::ChordTree(std::span<const Vec3> points) {
  const std::size_t n = points.size() - 1;
  a_.reserve(n);
  e_.reserve(n);
  inv_.reserve(n);
  double scale = 0.0;
  std::vector<Vec3> lo(n), hi(n);
  for (std::size_t k = 0; k < n; ++k) {
    a_.push_back(points[k]);
    e_.push_back(points[k + 1] - points[k]);
    inv_.push_back(1.0 / glm::dot(e_.back(), e_.back()));
    const Vec3 b = a_[k] + e_[k];  // the far end as distance2() computes it
    lo[k] = glm::min(a_[k], b);
    hi[k] = glm::max(a_[k], b);
    const Vec3 m = glm::max(glm::abs(lo[k]), glm::abs(hi[k]));
    scale = std::max({scale, m.x, m.y, m.z});
  }
  tree_ = BoxTree(lo, hi, kMarginOfScale * scale);
}

bool ChordTree::nearest(const Vec3& x, double limit2, Hit& hit) const {
  double best = limit2;
  bool found = false;
  tree_.nearest(x, best, kSlack, [&](std::uint32_t k) {
    double t = 0.0;
    const double d2 = distance2(x, k, t);
    if (d2 < best || (found && d2 == best && k < hit.chord)) {
      best = d2;
      hit = {k, t, d2};
      found = true;
    }
    return best;
  });
  return found;
}

std::size_t ChordTree::memoryBytes() const {
  return a_.capacity() * sizeof(Vec3) + e_.capacity() * sizeof(Vec3) +
         inv_.capacity() * sizeof(double) + tree_.memoryBytes();
}

}  // namespace spacewarp::detail
