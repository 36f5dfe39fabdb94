#include <spacewarp/nonlinear/detail/box_tree.h>

#include <algorithm>
#include <limits>

namespace spacewarp::detail {

namespace {
constexpr std::uint32_t kLeafItems = 4;
}  // namespace

BoxTree::BoxTree(std::span<const Vec3> lo, std::span<const Vec3> hi, double margin)
    : margin_(margin) {
  const auto n = static_cast<std::uint32_t>(lo.size());
  order_.resize(n);
  for (std::uint32_t i = 0; i < n; ++i) order_[i] = i;
  nodes_.reserve(2 * (n / kLeafItems + 1));
  nodes_.emplace_back();
  build(0, 0, n, lo, hi);
  nodes_.shrink_to_fit();
}

// Fills node `self` for order_[begin, end) and its subtree.
void BoxTree::build(std::uint32_t self, std::uint32_t begin, std::uint32_t end,
                    std::span<const Vec3> lo, std::span<const Vec3> hi) {
  Vec3 bl(std::numeric_limits<double>::infinity()), bh = -bl;
  Vec3 cl = bl, ch = bh;
  for (std::uint32_t i = begin; i < end; ++i) {
    const std::uint32_t k = order_[i];
    bl = glm::min(bl, lo[k]);
    bh = glm::max(bh, hi[k]);
    cl = glm::min(cl, lo[k] + hi[k]);  // twice the centre: same order, no rounding
    ch = glm::max(ch, lo[k] + hi[k]);
  }
  nodes_[self].lo = bl - Vec3(margin_);
  nodes_[self].hi = bh + Vec3(margin_);
  nodes_[self].begin = begin;
  if (end - begin <= kLeafItems) {
    nodes_[self].count = end - begin;
    return;
  }
  const Vec3 ext = ch - cl;
  const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : ext.y >= ext.z ? 1 : 2;
  const std::uint32_t mid = begin + (end - begin) / 2;
  // Ties by index, so the split does not depend on the selection's implementation.
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](std::uint32_t i, std::uint32_t j) {
                     const double ci = lo[i][axis] + hi[i][axis], cj = lo[j][axis] + hi[j][axis];
                     return ci < cj || (ci == cj && i < j);
                   });
  const auto child = static_cast<std::uint32_t>(nodes_.size());
  nodes_[self].child = child;
  nodes_.resize(nodes_.size() + 2);  // the children side by side
  build(child, begin, mid, lo, hi);
  build(child + 1, mid, end, lo, hi);
}

}  // namespace spacewarp::detail
