#pragma once
// Nearest chord of a polyline: a bounding-volume hierarchy (box_tree.h) over its chords with a
// branch-and-bound query. Built once per wire (O(n log n) time, O(n) memory, deterministic); used
// by WiresWarp for the closest point of a reference curve.

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

#include <spacewarp/core/math.h>
#include <spacewarp/nonlinear/detail/box_tree.h>

namespace spacewarp::detail {

class ChordTree {
 public:
  /// The nearest chord k of x, its parameter t ∈ [0, 1] (point a_k + t e_k) and squared distance.
  struct Hit {
    std::uint32_t chord = 0;
    double t = 0.0;
    double distance2 = 0.0;
  };

  /// The chords between consecutive points (at least 2, fewer than 2^32, finite, consecutive ones
  /// distinct).
  explicit ChordTree(std::span<const Vec3> points);

  /// The chord nearest to x among those at squared distance < limit2 (false if none): the least
  /// squared distance as computed by distance2(), the lowest chord index among equal ones, so the
  /// result is that of checking every chord in index order. Branch and bound: the nearer child
  /// box first, boxes farther than the best so far (or than the limit) skipped.
  bool nearest(const Vec3& x, double limit2, Hit& hit) const;

  /// x's squared distance to chord k and the parameter of its closest point.
  double distance2(const Vec3& x, std::uint32_t k, double& t) const {
    const Vec3 rel = x - a_[k];
    t = std::clamp(glm::dot(rel, e_[k]) * inv_[k], 0.0, 1.0);
    const Vec3 off = rel - t * e_[k];
    return glm::dot(off, off);
  }

  std::size_t chords() const { return a_.size(); }
  /// The bytes held (chords and tree).
  std::size_t memoryBytes() const;

 private:
  std::vector<Vec3> a_, e_;  // chord k: a_k + t e_k, t ∈ [0, 1]
  std::vector<double> inv_;  // 1 / |e_k|²
  BoxTree tree_;             // over the chords' boxes
};

}  // namespace spacewarp::detail
