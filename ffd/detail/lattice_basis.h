#pragma once
// Internal: the per-axis basis functions of a lattice, shared by Lattice (weights and
// gradients) and LatticeWarp's batch kernel. Not part of the public API.
//
// Each function evaluates, at the axis parameter u ∈ [0, 1], the weights of a contiguous window
// of control indices start .. start + count − 1 (count = 2 trilinear, 4 B-spline, n Bernstein)
// and, when `dw` is not null, their derivatives d/du. It returns start.

#include <algorithm>
#include <cmath>

#include <spacewarp/core/math.h>
#include <spacewarp/ffd/lattice.h>

namespace spacewarp::detail {

/// Points within this many box extents of a face count as on it (rounding of toLocal()).
inline constexpr double kFaceTolerance = 1e-12;

/// The box of a lattice, in the form the per-point code needs.
struct BoxFrame {
  Vec3 origin{0.0};
  Vec3 row[3];       // axis / extent: u_a = dot(x − origin, row[a])
  double extent[3];  // world units
  LatticeOutside outside = LatticeOutside::Identity;
  double falloffDistance = 1.0;  // world units

  explicit BoxFrame(const LatticeOptions& p) : origin(p.origin), outside(p.outside) {
    for (int a = 0; a < 3; ++a) {
      row[a] = p.axes[a] / p.extents[a];
      extent[a] = p.extents[a];
    }
    falloffDistance = p.falloff * std::sqrt(p.extents.x * p.extents.x + p.extents.y * p.extents.y +
                                            p.extents.z * p.extents.z);
  }
};

/// Where x is evaluated: u (clamped into [0, 1]³), which axes were clamped (their derivative
/// is 0), and the factor s on the displacement (1 inside; 1 for Clamp, the falloff for Falloff)
/// with, when `gradS` is not null, its gradient (world units). Returns false if x does not move.
inline bool locate(const BoxFrame& f, const Vec3& x, double u[3], bool clamped[3], double& s,
                   Vec3* gradS) {
  const Vec3 d = x - f.origin;
  bool outside = false;
  double excess[3];  // world-unit distance beyond the box along each axis (signed)
  for (int a = 0; a < 3; ++a) {
    const double t = glm::dot(d, f.row[a]);
    // NaN-safe: a NaN coordinate clamps to 0 (and counts as outside), so that no NaN ever
    // reaches the integer cell index.
    const double c = t > 0.0 ? (t < 1.0 ? t : 1.0) : 0.0;
    u[a] = c;
    const bool out = !(t >= -kFaceTolerance && t <= 1.0 + kFaceTolerance);
    clamped[a] = out;
    excess[a] = out ? (t - c) * f.extent[a] : 0.0;
    outside = outside || out;
  }
  s = 1.0;
  if (gradS) *gradS = Vec3(0.0);
  if (!outside) return true;
  switch (f.outside) {
    case LatticeOutside::Identity:
      return false;
    case LatticeOutside::Clamp:
      return true;
    case LatticeOutside::Falloff:
      break;
  }
  const double r = std::sqrt(excess[0] * excess[0] + excess[1] * excess[1] + excess[2] * excess[2]);
  const double t = r / f.falloffDistance;
  if (!(t < 1.0)) return false;
  s = 1.0 - t * t * (3.0 - 2.0 * t);
  if (gradS && r > 0.0) {
    const double dsdr = -6.0 * t * (1.0 - t) / f.falloffDistance;
    // ∇r = (x − p) / r, and x − p = Σ_a excess_a axis_a with axis_a = row_a extent_a.
    for (int a = 0; a < 3; ++a) *gradS += (dsdr * excess[a] * f.extent[a] / r) * f.row[a];
  }
  return true;
}

/// Bernstein lattices are limited to this many control points per axis (degree 31): beyond it
/// the global polynomial basis is numerically useless and the dense rows grow without bound.
inline constexpr int kMaxBernsteinResolution = 32;

/// The cell of the parameter t ∈ [0, n − 1] on an axis of n control points, and the fraction
/// in it: t = n − 1 (the upper face) lies in the last cell with fraction 1, never in a cell
/// n − 1 that does not exist.
inline int cellOf(double t, int n, double& f) {
  const int c = std::min(static_cast<int>(t), n - 2);
  f = t - c;
  return c;
}

inline int trilinearAxis(double u, int n, double* w, double* dw) {
  const double scale = n - 1;
  double f = 0.0;
  const int c = cellOf(u * scale, n, f);
  w[0] = 1.0 - f;
  w[1] = f;
  if (dw) {
    dw[0] = -scale;
    dw[1] = scale;
  }
  return c;
}

// Uniform cubic B-spline on controls at the integers 0 .. n − 1, with one phantom control at each
// end folded into the real ones. LatticeEnds::Extrapolate: the phantoms are extrapolated
// linearly (c₋₁ = 2c₀ − c₁, c_n = 2c_{n−1} − c_{n−2}); Repeat: they repeat the end controls
// (c₋₁ = c₀, c_n = c_{n−1}), Blender's lattice. Requires n ≥ 4, so that the two folds never meet.
template <LatticeEnds Ends>
inline int bsplineAxisWith(double u, int n, double* w, double* dw) {
  const double scale = n - 1;
  double f = 0.0;
  const int c = cellOf(u * scale, n, f);
  const double g = 1.0 - f;
  const double f2 = f * f;
  const double f3 = f2 * f;
  double b[4] = {g * g * g / 6.0, (3.0 * f3 - 6.0 * f2 + 4.0) / 6.0,
                 (-3.0 * f3 + 3.0 * f2 + 3.0 * f + 1.0) / 6.0, f3 / 6.0};
  double db[4] = {-0.5 * g * g * scale, (1.5 * f2 - 2.0 * f) * scale, (-1.5 * f2 + f + 0.5) * scale,
                  0.5 * f2 * scale};
  constexpr bool repeat = Ends == LatticeEnds::Repeat;
  if (c == 0) {  // controls −1 (phantom), 0, 1, 2 → 0, 1, 2 (and a zero for 3)
    w[0] = repeat ? b[1] + b[0] : b[1] + 2.0 * b[0];
    w[1] = repeat ? b[2] : b[2] - b[0];
    w[2] = b[3];
    w[3] = 0.0;
    if (dw) {
      dw[0] = repeat ? db[1] + db[0] : db[1] + 2.0 * db[0];
      dw[1] = repeat ? db[2] : db[2] - db[0];
      dw[2] = db[3];
      dw[3] = 0.0;
    }
    return 0;
  }
  if (c == n - 2) {  // controls n − 3, n − 2, n − 1, n (phantom) → n − 4 (a zero) .. n − 1
    w[0] = 0.0;
    w[1] = b[0];
    w[2] = repeat ? b[1] : b[1] - b[3];
    w[3] = repeat ? b[2] + b[3] : b[2] + 2.0 * b[3];
    if (dw) {
      dw[0] = 0.0;
      dw[1] = db[0];
      dw[2] = repeat ? db[1] : db[1] - db[3];
      dw[3] = repeat ? db[2] + db[3] : db[2] + 2.0 * db[3];
    }
    return n - 4;
  }
  for (int m = 0; m < 4; ++m) w[m] = b[m];
  if (dw)
    for (int m = 0; m < 4; ++m) dw[m] = db[m];
  return c - 1;
}

inline int bsplineAxis(double u, int n, double* w, double* dw) {
  return bsplineAxisWith<LatticeEnds::Extrapolate>(u, n, w, dw);
}

inline int bsplineRepeatAxis(double u, int n, double* w, double* dw) {
  return bsplineAxisWith<LatticeEnds::Repeat>(u, n, w, dw);
}

// Bernstein polynomials of degree n − 1 (all n weights), by the triangular recurrence
// B_j^d = (1 − u) B_j^{d−1} + u B_{j−1}^{d−1}; derivatives d (B_{j−1}^{d−1} − B_j^{d−1}).
inline int bernsteinAxis(double u, int n, double* w, double* dw) {
  const int degree = n - 1;
  const double v = 1.0 - u;
  w[0] = 1.0;
  for (int d = 1; d <= degree; ++d) {
    if (d == degree && dw) {
      for (int j = 0; j <= degree; ++j) {
        const double left = j > 0 ? w[j - 1] : 0.0;
        const double right = j < degree ? w[j] : 0.0;
        dw[j] = degree * (left - right);
      }
    }
    w[d] = u * w[d - 1];
    for (int j = d - 1; j > 0; --j) w[j] = v * w[j] + u * w[j - 1];
    w[0] = v * w[0];
  }
  return 0;
}

}  // namespace spacewarp::detail
