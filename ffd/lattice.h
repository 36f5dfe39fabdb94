#pragma once
// Lattice free-form deformation (Sederberg & Parry, "Free-form deformation of solid geometric
// models", SIGGRAPH 1986): an oriented box filled with a regular grid of control points, and a
// basis that blends the control points' displacements into a displacement of every point.
//
// With (u, v, w) ∈ [0, 1]³ the point's position in the box (u along the first axis, ...), the
// deformed position is x' = x + Σ_ijk B_i(u) B_j(v) B_k(w) (P_ijk − P⁰_ijk), P⁰ the rest grid.
// The three bases all reproduce the rest grid exactly (x' = x at rest) and affine maps of it:
//
// - Trilinear: piecewise linear per axis, 2 × 2 × 2 = 8 weights per point, C⁰ across cells.
// - Bernstein: Sederberg & Parry's tensor-product Bernstein polynomials of degree
//   resolution − 1 per axis; every control point influences every point; C^∞ inside.
// - BSpline: uniform cubic B-splines, 4 × 4 × 4 = 64 weights per point, C² everywhere inside.
//   Boundary convention: one phantom control beyond each face, extrapolated linearly from the
//   last two (c₋₁ = 2c₀ − c₁), so the spline interpolates the face controls, has zero second
//   derivative across the faces ("natural" ends) and the regular rest grid is exactly the
//   identity up to and including the faces. LatticeEnds::Repeat instead repeats the face
//   control as the phantom (c₋₁ = c₀), as Blender's lattice does: see LatticeEnds.
//
// Points on the box planes belong to the box: a point at u = 1 uses the last cell (see PyGeM
// issue #272), and points within 1e-12 box extents of a face are evaluated on the face.

#include <array>
#include <span>
#include <vector>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/math.h>

namespace spacewarp {

/// The basis of a lattice (see the top of this header).
enum class LatticeBasis { Trilinear, Bernstein, BSpline };

/// The phantom controls of the B-spline basis beyond each face (the other bases have none).
/// Both act on displacements, so the rest lattice is the identity with either; they differ
/// only within the first and last cell along each axis (one cell: 1/(resolution − 1) of the
/// box) and agree exactly deeper inside.
enum class LatticeEnds {
  /// c₋₁ = 2c₀ − c₁: the spline interpolates the face controls and reproduces affine poses of
  /// the grid (a scaled or sheared lattice scales or shears every point) up to the faces.
  Extrapolate,
  /// c₋₁ = c₀ (Blender's lattice: its control indices clamp at the ends): a face control weighs
  /// 5/6 on its face and its neighbour 1/6, so the spline does not interpolate the face controls
  /// and an affine pose is reproduced only deeper than one cell from the faces: on a face the
  /// point moves by (5 d₀ + d₁) / 6 (d₀ the face control's displacement, d₁ its neighbour's)
  /// where extrapolate moves it by d₀.
  Repeat,
};

/// What happens to points outside the box. d(p) is the lattice displacement at the point p of
/// the box surface nearest to x.
enum class LatticeOutside {
  /// Outside points do not move. Continuous at the box surface only where the surface does not
  /// move (boundary controls at rest); otherwise the position jumps by d(p) across the surface.
  Identity,
  /// Blender's behaviour: x' = x + d(p). Continuous (C⁰) across the box surface for any pose;
  /// the displacement is constant along each outward normal (and on the corner and edge
  /// regions, along the rays from the nearest corner or edge).
  Clamp,
  /// VTK's "Zero" border: x' = x + s(r / R) d(p) with r = |x − p| the distance to the box, R the
  /// falloff distance (LatticeOptions::falloff × box diagonal) and s(t) = 1 − t²(3 − 2t) for
  /// t < 1, 0 beyond. Continuous (C⁰) across the box surface, C¹ at r = R, and exactly the
  /// identity farther than R from the box.
  Falloff,
};

/// Parameters of a Lattice. Validated by Lattice's constructor.
struct LatticeOptions {
  /// The corner of the box at (u, v, w) = (0, 0, 0), world units. Default: the origin.
  Vec3 origin{0.0};
  /// The box's edge directions: orthonormal (within 1e-9), any handedness. Default: x, y, z.
  std::array<Vec3, 3> axes{Vec3(1.0, 0.0, 0.0), Vec3(0.0, 1.0, 0.0), Vec3(0.0, 0.0, 1.0)};
  /// Edge lengths along the three axes, world units, finite and positive. Default: a unit cube.
  Vec3 extents{1.0};
  /// Control points per axis (l, m, n): ≥ 2, ≥ 4 for BSpline, ≤ 32 for Bernstein; at most
  /// 2³¹ − 1 in all. Default: 2 × 2 × 2 (the box corners).
  std::array<int, 3> resolution{2, 2, 2};
  /// The basis. Default: trilinear.
  LatticeBasis basis = LatticeBasis::Trilinear;
  /// The B-spline basis's ends. Default: extrapolate. Repeat needs the B-spline basis.
  LatticeEnds ends = LatticeEnds::Extrapolate;
  /// The outside-the-box policy. Default: outside points do not move.
  LatticeOutside outside = LatticeOutside::Identity;
  /// The falloff distance of LatticeOutside::Falloff, relative to the box diagonal; finite and
  /// positive. Default 0.1: the displacement fades out over a tenth of the diagonal.
  double falloff = 0.1;
};

/// The struct's former name, kept for code written against it.
using LatticeParams [[deprecated("renamed LatticeOptions")]] = LatticeOptions;

/// An oriented box with a regular grid of control points. Control point (i, j, k) is number
/// index(i, j, k) = i + l (j + m k): i fastest, then j, then k. Immutable; every method is const
/// and thread-safe.
class Lattice {
 public:
  /// Throws InvalidInput naming the parameter at fault: a resolution below 2 (below 4 for
  /// BSpline, above 32 for Bernstein), axes that are not finite, not unit or not orthogonal,
  /// extents that are not finite and positive, a non-finite origin or falloff.
  explicit Lattice(const LatticeOptions& params);

  const LatticeOptions& params() const { return params_; }

  /// Archive (core/archive.h): the options (no tag: a lattice is always part of a warp or of
  /// coordinates); load() rebuilds the lattice through the constructor.
  void save(ArchiveWriter& out) const;
  static Lattice load(ArchiveReader& in);
  /// The parameters load() builds the lattice from, not built yet: a loader that stores arrays
  /// sized by the resolution compares them first, so that hostile bytes cannot make it build
  /// a huge lattice before being refused.
  static LatticeOptions loadOptions(ArchiveReader& in);
  LatticeBasis basis() const { return params_.basis; }
  const std::array<int, 3>& resolution() const { return params_.resolution; }

  /// l × m × n.
  std::size_t controlPointCount() const { return rest_.size(); }
  std::size_t index(int i, int j, int k) const;

  /// The regular rest grid (controlPointCount() points, world units).
  std::span<const Vec3> restControlPoints() const { return rest_; }

  /// Length of the box diagonal, world units.
  double diagonal() const;

  /// (u, v, w): the position of x in the box, [0, 1]³ inside (not clamped).
  Vec3 toLocal(const Vec3& x) const;
  /// The world position of the box coordinates (u, v, w).
  Vec3 toWorld(const Vec3& uvw) const;

  /// At most how many weights of one point are non-zero: 8 trilinear, 64 B-spline, all control
  /// points for Bernstein.
  std::size_t maxNonZeros() const;

  /// The weights of x's displacement (the terms of x' = x + Σ w_c d_c), sorted by control
  /// index, into `out` (at least maxNonZeros() entries); returns how many were written (0 for
  /// points that do not move). Windows are written whole, so some weights may be 0. When
  /// `gradients` is not empty (at least maxNonZeros() entries), also writes ∇w_c (per world
  /// unit), one-sided (from inside) on the box surface. Throws InvalidInput if x is not finite
  /// or a span is too short.
  std::size_t sparseWeights(const Vec3& x, std::span<SparseWeight> out,
                            std::span<Vec3> gradients = {}) const;

 private:
  LatticeOptions params_;
  std::vector<Vec3> rest_;
};

}  // namespace spacewarp
