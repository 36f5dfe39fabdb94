#pragma once
// The Warp interface: a map x -> x' of 3D space. Every warp in spacewarp implements it, and
// everything that consumes warps (soups, point sets, volumes, inversion, normals) takes it.
// Inversion lives in core/inverse.h.

#include <algorithm>
#include <cstddef>
#include <limits>
#include <optional>
#include <span>

#include <spacewarp/core/math.h>

namespace spacewarp {

class Warp;
class ArchiveReader;
class ArchiveWriter;

/// The points of a batch that a warp or coordinate function could not map (outside its domain,
/// e.g. outside a cage): how many, the index of the first, and (for warps) which warp's kernel
/// could not map them, which is the one to explain it (a stage of a composition).
struct UnmappedPoints {
  std::size_t count = 0;
  std::size_t first = std::numeric_limits<std::size_t>::max();
  const Warp* by = nullptr;

  void add(std::size_t index) {
    ++count;
    first = std::min(first, index);
  }
  /// Points of another range. Counts add up when the same kernel reported both; otherwise the
  /// report whose first point comes first is kept.
  void merge(const UnmappedPoints& other) {
    if (other.count == 0) return;
    if (count == 0 || by == other.by) {
      count += other.count;
      first = std::min(first, other.first);
      by = other.by;
    } else if (other.first < first) {
      *this = other;
    }
  }
};

/// A map of 3D space, x -> x'. Every method is const and thread-safe.
class Warp {
 public:
  virtual ~Warp() = default;

  /// The warped position of x (world units).
  virtual Vec3 apply(const Vec3& x) const = 0;

  /// The Jacobian d x' / d x at x. The default is central differences with a step of
  /// cbrt(machine epsilon) * max(1, |x|_inf) ~ 6e-6 per axis (about 1e-10 relative error for
  /// smooth warps);
  /// warps whose math allows it override this with the analytic Jacobian.
  virtual Mat3 jacobian(const Vec3& x) const;

  /// The preimage of y in closed form, for warps that have one (twist, taper, bend within its
  /// range, affine, compositions of these): inverse() then returns it instead of iterating.
  /// Empty (the default) where there is none, or where y has no preimage the warp can name
  /// (e.g. a singular affine map). What it returns is not checked here: inverse() measures
  /// its residual.
  virtual std::optional<Vec3> exactInverse(const Vec3& y) const;

  /// out[i] = apply(in[i]) for every i, in parallel (TBB): [0, n) is cut into ranges of
  /// batchGrain() points, each warped by applyRange(). The ranges depend only on n, so the
  /// result does not depend on the number of threads. `in` and `out` must have the same size;
  /// they may be the same span. Throws InvalidInput when the sizes differ, and what
  /// throwUnmapped() throws when some points could not be warped.
  void applyBatch(std::span<const Vec3> in, std::span<Vec3> out) const;

  /// applyBatch() of the block [begin, end) of a larger batch `in` into out[begin, end) (`out`
  /// has in.size() entries), for callers that cut a batch into blocks (progress, cancellation):
  /// errors name indices into `in` and its size; the count is of the block's unmapped points.
  void applyBatch(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                  std::size_t end) const;

  /// Writes this warp to an archive (core/archive.h): its tag, then what rebuilds it (solved
  /// state included, so that loading does not solve again). The default throws InvalidInput
  /// naming the type: a warp that cannot be saved (one made in Python, an internal cache).
  virtual void save(ArchiveWriter& out) const;

 protected:
  /// Points per range of applyBatch(): enough work to amortise a task, few enough to balance.
  virtual std::size_t batchGrain() const { return 4096; }

  /// The batch kernel: out[i] = apply(in[i]) for i in [begin, end) (indices into the whole
  /// batch; `in` and `out` may alias, each point is read before it is written). Called on
  /// disjoint ranges from several threads at once. Returns the points it could not warp (left
  /// as they were); the default calls apply() per point and reports none.
  virtual UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                    std::size_t begin, std::size_t end) const;

  /// Throws for the points of the batch `in` that applyRange() could not warp. The default
  /// throws InvalidInput with their number and the first one's index.
  [[noreturn]] virtual void throwUnmapped(const UnmappedPoints& unmapped,
                                          std::span<const Vec3> in) const;

 private:
  friend class ComposedWarp;  // runs its stages' kernels range by range
};

/// The normal n at x carried through the warp: J^-T n, normalised, computed through the
/// cofactor matrix det(J) J^-T so that it stays defined where J is singular: at rank 2 it is
/// the normal of the image plane, at rank 1 or 0 a zero vector (never NaN). J is first scaled
/// by a power of two (exactly), so entries near 1e300 or 1e-300 give the normal too.
Vec3 transformNormal(const Warp& warp, const Vec3& x, const Vec3& n);

/// The same with the Jacobian J at the normal's point given.
Vec3 transformNormal(const Mat3& jacobian, const Vec3& n);

/// Whether J is numerically singular (or not finite): |det J| at most 1e-14 times the product
/// of its column lengths, i.e. zero up to rounding at J's own scale — computed with the
/// columns scaled to unit length first, so that the verdict is the same for J and s J at any
/// scale s (entries of 1e300 or 1e-300 included). Normals are undefined there. (A strongly
/// anisotropic but invertible J is not singular: its normals are defined. A J whose columns
/// are nearly dependent, such as the huge shear of a twist at a rate of 1e100 away from its
/// axis, is singular in double precision even though det J = 1: J^-T n cannot be computed.)
bool isSingularJacobian(const Mat3& jacobian);

/// The tangent vector v at x carried through the warp: J v (not normalised).
Vec3 transformVector(const Warp& warp, const Vec3& x, const Vec3& v);

}  // namespace spacewarp
