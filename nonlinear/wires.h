#pragma once
// Wires: Singh & Fiume, "Wires: a geometric deformation technique" (SIGGRAPH 1998). A wire is a
// reference curve R and a deformed curve W; space near R follows the change from R to W (scaled,
// rotated and moved about the closest point of R), fading out at the wire's radius of influence.

#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <spacewarp/core/warp.h>

namespace spacewarp {

class ArchiveReader;
class ArchiveWriter;

namespace detail {
class BoxTree;
}  // namespace detail

/// How a wire's curve passes through its points.
enum class WireCurve {
  Polyline,    ///< Straight segments between the points.
  CatmullRom,  ///< The uniform Catmull-Rom spline through the points (C¹; the end spans use the
               ///< reflected neighbour, 2 P_0 − P_1, as their outer control point).
};

/// The drop-off f: [0, 1] → [0, 1], f(0) = 1, f(1) = 0, of a wire's influence.
enum class WireDropoff {
  Smooth,  ///< f(x) = (1 − x²)²: C¹ at both ends (f'(0) = f'(1) = 0), the paper's choice.
  Linear,  ///< f(x) = 1 − x.
};

/// "polyline" or "catmull-rom".
std::string wireCurveName(WireCurve curve);
/// The curve named "polyline" or "catmull-rom"; throws InvalidInput for any other name.
WireCurve wireCurveFromName(std::string_view name);
/// "smooth" or "linear".
std::string wireDropoffName(WireDropoff dropoff);
/// The drop-off named "smooth" or "linear"; throws InvalidInput for any other name.
WireDropoff wireDropoffFromName(std::string_view name);

/// One wire. R and W are parameterised alike, by the index of their points (u ∈ [0, n − 1]; point
/// k at u = k), so that R(u) corresponds to W(u).
struct Wire {
  /// The reference curve's points: n ≥ 2, world units, no two consecutive ones equal (closer
  /// than 1e-12 of the curve's bounding-box diagonal).
  std::vector<Vec3> rest;
  /// The deformed curve's points: as many as `rest`, same conditions.
  std::vector<Vec3> deformed;
  /// Radius of influence r, world units; finite, > 0. Points farther than r from R do not move.
  double radius = 1.0;
  /// Inner radius r₀ ∈ [0, r), world units; default 0. Within r₀ of R the influence is full
  /// (F = 1), so a rigid motion of the wire moves that whole tube rigidly; between r₀ and r,
  /// F = f((d − r₀) / (r − r₀)). With r₀ = 0 only the curve itself has F = 1 (the paper).
  double innerRadius = 0.0;
  /// Scale s about the curve, finite, > 0; default 1 (none). A point at distance d from R moves
  /// to distance (1 + (s − 1) F) d of it.
  double scale = 1.0;
  /// The drop-off f; default Smooth, (1 − x²)².
  WireDropoff dropoff = WireDropoff::Smooth;
  /// How the curves pass through their points; default Polyline.
  WireCurve curve = WireCurve::Polyline;
};

/// Options of WiresWarp.
struct WiresOptions {
  /// The paper's "localizing" exponent m ≥ 0 of the combination of several wires:
  /// x' = x + Σ Δx_i |Δx_i|^m / Σ |Δx_i|^m. m = 0 averages the moves of the wires that move x;
  /// larger m lets the wire that moves x most dominate. Default 1. Unused for a single wire.
  /// With m < 1 the map jumps where another wire's influence starts (a wire counts as soon as
  /// it moves x at all), so m ≥ 1 where wires overlap.
  double locality = 1.0;
};

/// The wires deformation. For one wire and a point x: u = the parameter of the closest point of
/// R to x, d = |x − R(u)|, F = 1 for d ≤ r₀, f((d − r₀)/(r − r₀)) for r₀ < d < r, 0 for d ≥ r;
/// then (the paper's three steps, about R(u))
///   x_s = R(u) + (1 + (s − 1) F)(x − R(u))            scale,
///   x_r = R(u) + rot(M(u), F)(x_s − R(u))              rotate,
///   x'  = x_r + F (W(u) − R(u))                        translate,
/// where M(u) is the rotation taking R's frame at u to W's frame at u and rot(M, F) the rotation
/// about M's axis by F times its angle, the angle taken continuously along the curve, in
/// [0, 2π] (not reduced to the short way: M's quaternion keeps its sign from sample to sample,
/// starting with w ≥ 0 at u = 0, so space does not tear where M passes a half turn; a wire whose
/// M reaches a full turn has rot(M, F) singular there). The frames are rotation-minimising (double
/// reflection, Wang et al. 2008) frames [tangent, normal, binormal], so M(u) takes R'(u) to W'(u)
/// and carries the curves' twist, fixed by M(0): R's first frame carried by the best rigid fit Q
/// of the rest points onto the deformed points (Kabsch), then turned by the smallest rotation
/// taking Q R'(0) to W'(0). So a rigid motion Q of a non-straight wire gives M(u) = Q everywhere
/// and moves the region F = 1 rigidly (to rounding). Where that fit is not firm (its turn about
/// the curve flips between nearly equal wires: W nearly straight, or bent unlike R, e.g. an
/// S-shape over an arch), M(0)'s turn about W'(0) is faded towards that of the smallest rotation
/// taking R'(0) to W'(0), in proportion to σ₂ + sign(det H) σ₃ of the points' cross-covariance H
/// over half of R's spread off its principal line (the value for a rigid motion; full from there
/// on), so the twist changes little for small changes of W. A straight R (off its line by less
/// than 1e-12 of its size) uses the smallest rotation alone (a turn about it would be invisible).
/// Continuity in W cannot hold everywhere together with rigid motions (a W bent like R but
/// mirrored is R turned a half turn): it fails where that fade is partial and Q's turn is
/// opposite to the smallest rotation's (a mirrored bend weaker than half of R's).
///
/// Frames and tangents are computed at sample points and M is interpolated between them
/// (normalised lerp of the quaternions, which is slerp to within the square of the samples'
/// angle): for polylines the samples are the points, with the tangent the mean of the two segment
/// directions (so M is continuous along the curve); for Catmull-Rom 16 samples per span, exact
/// spline tangents. Closest points: exact for polylines; for Catmull-Rom the nearest of the
/// samples' chords refined by Newton's method on the cubic (to rounding, away from the curve's
/// medial axis, where the closest point jumps anyway). The nearest chord comes from a
/// bounding-volume hierarchy over R's chords (detail/chord_tree.h: median splits, O(n) memory,
/// branch and bound; ties to the lowest chord index, as a scan would), so its cost grows with the
/// log of the sample count, not with the density. Points outside a wire's box grown by its reach
/// skip it in a few comparisons, and a hierarchy over those boxes finds the few wires near a
/// point among many. Points farther than r from every wire are returned unchanged (bit for bit).
///
/// Cost: about 75 ns of CPU per point for one polyline wire, 145 ns for one Catmull-Rom wire, with
/// a third of the points within r (a two-wire rig in bench/nonlinear_bench_wires.cpp); a wire of
/// n samples typically costs O(log n) per point near it, and building is O(n log n) time, O(n)
/// memory.
///
/// Several wires: x' = x + Σ Δx_i w_i / Σ w_i with Δx_i the move of wire i alone and
/// w_i = |Δx_i|^m (0 for Δx_i = 0). One wire: x' is that wire's x' exactly.
///
/// Properties: R(u) goes to W(u) (to rounding); W = R and s = 1 is the identity bit for bit. The
/// map is continuous wherever the closest point of R is (it jumps on R's medial axis within r, as
/// in the paper: keep r below the curve's radius of curvature), except at a closed wire's seam:
/// a wire whose last point is its first is still treated as open (Catmull-Rom ends reflected, and
/// R's and W's frames need not close up around the loop, so M at the end differs from M at the
/// start), and space jumps across the seam where the closest point passes from the end to the
/// start (by 0.05 at 0.05 from a unit-size loop reshaped by a fifth of its size). Jacobian:
/// analytic, through the closest point's parameter (dt/dx = R' / (|R'|² − R''·(x − R))), the
/// drop-off and the rotation (SO(3)'s left Jacobian for the power F of the interpolated rotation),
/// and the blend's weights; where u(x) is not differentiable (the medial axis, a polyline's
/// vertices' bisector planes) it is one side's. applyBatch runs in parallel; every result is
/// bit-identical to apply() for any thread count. Non-finite x is returned unchanged.
class WiresWarp final : public Warp {
 public:
  /// Throws InvalidInput naming the wire (its index) and the parameter for: no wires, fewer than
  /// 2 points, mismatched counts, non-finite points, repeated consecutive points, a radius that is
  /// not finite and > 0, an inner radius outside [0, r), a scale that is not finite and > 0, or a
  /// locality that is not finite and ≥ 0; also for a curve that spans too far for squared
  /// lengths to be finite (~1e154), a radius that takes the wire's reach beyond doubles, or more
  /// than 2^24 chords (polyline: points − 1; Catmull-Rom: 16 per span), about 0.4 kB each to
  /// build.
  explicit WiresWarp(std::vector<Wire> wires, const WiresOptions& options = {});
  ~WiresWarp() override;

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;

  std::span<const Wire> wires() const { return wires_; }
  const WiresOptions& options() const { return options_; }

  /// Archive tag "wires": the locality and every wire as given. The per-wire data built from
  /// them is rebuilt on loading (cheap and deterministic: the same results bit for bit).
  void save(ArchiveWriter& out) const override;
  /// Rebuilt through the constructor.
  static std::shared_ptr<const WiresWarp> load(ArchiveReader& in);

 protected:
  std::size_t batchGrain() const override { return 2048; }
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  struct Compiled;
  std::vector<Wire> wires_;
  WiresOptions options_;
  std::vector<std::unique_ptr<const Compiled>> compiled_;
  std::unique_ptr<const detail::BoxTree> index_;  // over the wires' reach boxes
};

}  // namespace spacewarp
