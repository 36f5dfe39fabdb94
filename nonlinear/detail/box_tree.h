#pragma once
// A bounding-volume hierarchy over axis-aligned boxes (median splits of their centres along the
// widest axis, ties by index: deterministic), O(n) memory, with the two queries WiresWarp needs:
// branch and bound for a nearest item and the items whose box holds a point.

#include <array>
#include <cstdint>
#include <span>
#include <utility>  // std::swap
#include <vector>

#include <spacewarp/core/math.h>

namespace spacewarp::detail {

class BoxTree {
 public:
  BoxTree() = default;
  /// Boxes [lo_i, hi_i] (fewer than 2^32, at least one), each grown by `margin`.
  BoxTree(std::span<const Vec3> lo, std::span<const Vec3> hi, double margin);

  /// Squared distance from x to node n's box (0 inside).
  double distance2(std::uint32_t n, const Vec3& x) const {
    const Vec3 gap = glm::max(glm::max(nodes_[n].lo - x, x - nodes_[n].hi), Vec3(0.0));
    return glm::dot(gap, gap);
  }

  /// Branch and bound: visits the leaves' items (visit(i) returns the bound so far, a squared
  /// distance) nearer box first, skipping boxes whose squared distance exceeds bound · slack.
  template <class Visit>
  void nearest(const Vec3& x, double bound, double slack, const Visit& visit) const {
    // Left uninitialised (std::pair would zero it on every query).
    std::array<std::uint32_t, kMaxDepth> stackNode;
    std::array<double, kMaxDepth> stackDistance;
    std::size_t size = 0;
    std::uint32_t node = 0;
    if (!(distance2(0, x) <= bound * slack)) return;
    for (;;) {
      const Node& n = nodes_[node];
      if (n.count > 0) {
        for (std::uint32_t i = n.begin; i < n.begin + n.count; ++i) bound = visit(order_[i]);
      } else {
        std::uint32_t near = n.child, far = n.child + 1;
        double dn = distance2(near, x), df = distance2(far, x);
        if (df < dn) {
          std::swap(near, far);
          std::swap(dn, df);
        }
        if (dn <= bound * slack) {
          if (df <= bound * slack) {
            stackNode[size] = far;
            stackDistance[size++] = df;
          }
          node = near;
          continue;
        }
      }
      for (;;) {  // the next pushed box still within the bound
        if (size == 0) return;
        --size;
        if (stackDistance[size] <= bound * slack) {
          node = stackNode[size];
          break;
        }
      }
    }
  }

  /// Calls visit(i) for every item whose (grown) box holds x, in no particular order.
  template <class Visit>
  void containing(const Vec3& x, const Visit& visit) const {
    std::array<std::uint32_t, kMaxDepth> stack;
    std::size_t size = 0;
    stack[size++] = 0;
    while (size > 0) {
      const Node& n = nodes_[stack[--size]];
      if (!(x.x >= n.lo.x && x.y >= n.lo.y && x.z >= n.lo.z && x.x <= n.hi.x && x.y <= n.hi.y &&
            x.z <= n.hi.z))
        continue;
      if (n.count > 0) {
        for (std::uint32_t i = n.begin; i < n.begin + n.count; ++i) visit(order_[i]);
      } else {
        stack[size++] = n.child;
        stack[size++] = n.child + 1;
      }
    }
  }

  /// The bytes held.
  std::size_t memoryBytes() const {
    return order_.capacity() * sizeof(std::uint32_t) + nodes_.capacity() * sizeof(Node);
  }

 private:
  // Median splits halve the items per level: fewer than 2^32 need at most 32 levels (and the
  // stabbing query's stack at most one more entry per level).
  static constexpr std::size_t kMaxDepth = 72;
  struct Node {
    Vec3 lo, hi;              // the box of its items' boxes
    std::uint32_t begin = 0;  // its items: order_[begin, begin + count)
    std::uint32_t count = 0;  // 0 for an inner node
    std::uint32_t child = 0;  // an inner node's children: child, child + 1
  };
  void build(std::uint32_t self, std::uint32_t begin, std::uint32_t end, std::span<const Vec3> lo,
             std::span<const Vec3> hi);

  std::vector<std::uint32_t> order_;
  std::vector<Node> nodes_;  // nodes_[0] is the root
  double margin_ = 0.0;
};

}  // namespace spacewarp::detail
