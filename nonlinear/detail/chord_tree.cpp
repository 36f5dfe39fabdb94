#include <spacewarp/nonlinear/detail/chord_tree.h>

#include <algorithm>
#include <array>
#include <limits>

namespace spacewarp::detail {

namespace {

constexpr std::uint32_t kLeafChords = 4;
// Median splits halve the chords per level: fewer than 2^32 chords need at most 32 levels.
constexpr int kMaxDepth = 64;
// Pruning slack: a box is skipped only when it is farther than the best chord by more than the
// rounding of the two computed distances, so the result is that of checking every chord.
constexpr double kMarginOfScale = 1e-10;
constexpr double kSlack = 1.0 + 1e-9;

}  // namespace

ChordTree::ChordTree(std::span<const Vec3> points) {
  const std::size_t n = points.size() - 1;
  a_.reserve(n);
  e_.reserve(n);
  inv_.reserve(n);
  double scale = 0.0;
  for (const Vec3& p : points)
    scale = std::max({scale, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
  margin_ = kMarginOfScale * scale;
  std::vector<Vec3> centre(n);
  order_.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    a_.push_back(points[k]);
    e_.push_back(points[k + 1] - points[k]);
    inv_.push_back(1.0 / glm::dot(e_.back(), e_.back()));
    centre[k] = 0.5 * (points[k] + points[k + 1]);
    order_[k] = static_cast<std::uint32_t>(k);
  }
  nodes_.reserve(2 * (n / kLeafChords + 1));
  nodes_.emplace_back();
  build(0, 0, static_cast<std::uint32_t>(n), centre);
  nodes_.shrink_to_fit();
}

// Fills node `self` for order_[begin, end) and its subtree.
void ChordTree::build(std::uint32_t self, std::uint32_t begin, std::uint32_t end,
                      const std::vector<Vec3>& centre) {
  Vec3 lo(std::numeric_limits<double>::infinity()), hi = -lo;
  Vec3 clo = lo, chi = hi;
  for (std::uint32_t i = begin; i < end; ++i) {
    const std::uint32_t k = order_[i];
    lo = glm::min(lo, glm::min(a_[k], a_[k] + e_[k]));
    hi = glm::max(hi, glm::max(a_[k], a_[k] + e_[k]));
    clo = glm::min(clo, centre[k]);
    chi = glm::max(chi, centre[k]);
  }
  nodes_[self].lo = lo - Vec3(margin_);
  nodes_[self].hi = hi + Vec3(margin_);
  nodes_[self].begin = begin;
  if (end - begin <= kLeafChords) {
    nodes_[self].count = end - begin;
    return;
  }
  // Median of the chords' centres along the widest axis of the centres (ties by index, so the
  // split does not depend on the sort's implementation).
  const Vec3 ext = chi - clo;
  const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : ext.y >= ext.z ? 1 : 2;
  const std::uint32_t mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](std::uint32_t i, std::uint32_t j) {
                     const double ci = centre[i][axis], cj = centre[j][axis];
                     return ci < cj || (ci == cj && i < j);
                   });
  const auto child = static_cast<std::uint32_t>(nodes_.size());
  nodes_[self].child = child;
  nodes_.resize(nodes_.size() + 2);  // the children side by side
  build(child, begin, mid, centre);
  build(child + 1, mid, end, centre);
}

double ChordTree::boxDistance2(const Node& n, const Vec3& x) const {
  const Vec3 gap = glm::max(glm::max(n.lo - x, x - n.hi), Vec3(0.0));
  return glm::dot(gap, gap);
}

bool ChordTree::nearest(const Vec3& x, double limit2, Hit& hit) const {
  double best = limit2;
  bool found = false;
  std::array<std::pair<std::uint32_t, double>, kMaxDepth> stack;
  int size = 0;
  std::uint32_t node = 0;
  if (!(boxDistance2(nodes_[0], x) <= best * kSlack)) return false;
  for (;;) {
    const Node& n = nodes_[node];
    if (n.count > 0) {
      for (std::uint32_t i = n.begin; i < n.begin + n.count; ++i) {
        const std::uint32_t k = order_[i];
        double t = 0.0;
        const double d2 = distance2(x, k, t);
        if (d2 < best || (found && d2 == best && k < hit.chord)) {
          best = d2;
          hit = {k, t, d2};
          found = true;
        }
      }
    } else {
      std::uint32_t near = n.child, far = n.child + 1;
      double dn = boxDistance2(nodes_[near], x), df = boxDistance2(nodes_[far], x);
      if (df < dn) {
        std::swap(near, far);
        std::swap(dn, df);
      }
      if (dn <= best * kSlack) {
        if (df <= best * kSlack) stack[static_cast<std::size_t>(size++)] = {far, df};
        node = near;
        continue;
      }
    }
    for (;;) {  // the next pushed box still within reach of the best
      if (size == 0) return found;
      const auto [next, d] = stack[static_cast<std::size_t>(--size)];
      if (d <= best * kSlack) {
        node = next;
        break;
      }
    }
  }
}

std::size_t ChordTree::memoryBytes() const {
  return a_.capacity() * sizeof(Vec3) + e_.capacity() * sizeof(Vec3) +
         inv_.capacity() * sizeof(double) + order_.capacity() * sizeof(std::uint32_t) +
         nodes_.capacity() * sizeof(Node);
}

}  // namespace spacewarp::detail
