#pragma once
// Regularized Kelvinlets: de Goes & James, "Regularized Kelvinlets: sculpting brushes based on
// fundamental solutions of elasticity" (SIGGRAPH 2017). A brush is the displacement of an
// infinite elastic medium under a force (grab) or a force matrix (twist, scale, pinch) spread
// over a radius ε around a centre: smooth everywhere, decaying with distance, and no control
// structure at all.

#include <memory>
#include <string>
#include <string_view>

#include <spacewarp/core/warp.h>

namespace spacewarp {

class ArchiveReader;
class ArchiveWriter;

/// The brush kinds of the paper.
enum class KelvinletBrush {
  Grab,   ///< A force: the centre moves by `displacement`; |u| ~ 1/r far away.
  Twist,  ///< A torque: rotates the centre's neighbourhood by `angle` about `axis`; ~ 1/r².
  Scale,  ///< An isotropic force dipole: scales the centre's neighbourhood by `factor`; ~ 1/r².
  Pinch,  ///< A symmetric traceless force matrix: the centre's gradient is `matrix`; ~ 1/r².
};

/// How fast a brush fades with distance r ≫ ε (the paper's multi-scale extrapolation).
enum class KelvinletFalloff {
  Single,  ///< One radius ε: |u| ~ 1/r (grab) or 1/r² (twist, scale, pinch).
  /// Radii ε and 2ε combined: 1/r³ (grab), 1/r⁴ (pinch), 1/r⁶ (twist and scale, whose far
  /// field has no ε² term to cancel).
  Bi,
  /// Radii ε, 2ε and 4ε combined: 1/r⁵ (grab), 1/r⁶ (pinch; twist and scale as with Bi).
  Tri,
};

/// "single", "bi" or "tri".
std::string kelvinletFalloffName(KelvinletFalloff falloff);
/// The falloff named "single", "bi" or "tri"; throws InvalidInput for any other name.
KelvinletFalloff kelvinletFalloffFromName(std::string_view name);

/// "grab", "twist", "scale" or "pinch".
std::string kelvinletBrushName(KelvinletBrush brush);
/// The brush named "grab", "twist", "scale" or "pinch"; throws InvalidInput for any other name.
KelvinletBrush kelvinletBrushFromName(std::string_view name);

/// Options of KelvinletWarp. Only the keys of the chosen brush are used.
struct KelvinletOptions {
  KelvinletBrush brush = KelvinletBrush::Grab;
  Vec3 center{0.0};     ///< The brush's centre, world units.
  double radius = 1.0;  ///< Regularisation radius ε, world units: finite, > 0. Default 1.
  /// Poisson ratio ν in [0, 0.5]. Default 0.45. The formulas stay finite at ν = 0.5
  /// (incompressible: the grab and pinch displacements are then divergence-free). Twist and
  /// scale, once normalised, do not depend on ν (their elastic factor cancels). The shear
  /// modulus is not an option: the normalisation below cancels it.
  double poisson = 0.45;
  Vec3 displacement{0.0};    ///< Grab: the centre's displacement, world units.
  Vec3 axis{0.0, 0.0, 1.0};  ///< Twist: the rotation axis (any non-zero length).
  double angle = 0.0;        ///< Twist: radians, right-handed about `axis`.
  double factor = 1.0;       ///< Scale: the centre's scale factor, finite and > 0.
  /// Pinch: the centre's displacement gradient, symmetric and traceless (within 1e-12 of its
  /// norm), e.g. diag(s, −s, 0) stretches along x and squeezes along y.
  Mat3 matrix{0.0};
  /// Multi-scale falloff (default Single, the closed form). Bi and Tri combine the brush at
  /// radii ε, 2ε (and 4ε) with weights w_j (1, −1; or 1, −(ε₃² − ε₁²)/(ε₃² − ε₂²),
  /// (ε₂² − ε₁²)/(ε₃² − ε₂²)) that cancel the leading far-field terms, renormalised so that the
  /// centre still does exactly what the brush's parameters say; 2 or 3 times the cost.
  KelvinletFalloff falloff = KelvinletFalloff::Single;
  /// The brush applied as a composition of `steps` brushes of 1/steps of the edit each
  /// (displacement/steps with the grab centre following it, angle/steps, factor^(1/steps),
  /// matrix/steps), as the paper integrates large edits in time to avoid folds: cost and
  /// Jacobian cost grow linearly with steps. 1 (default) is the closed form. 1..10000.
  int steps = 1;
};

/// x' = x + u(x − c) for the regularised Kelvinlet u of the brush, with r = x − c,
/// ρ = sqrt(|r|² + ε²), a = 1/(4πμ) (μ cancels), b = a / (4(1 − ν)):
///   - grab:  u = s [((a − b)/ρ + a ε²/(2ρ³)) I + b r rᵀ/ρ³] f, f the displacement and
///            s = 2ε / (3a − 2b), so that u(0) = f exactly;
///   - twist: u = θ ψ(ρ) (n × r), ψ = (2ε³/5)(1/ρ³ + 3ε²/(2ρ⁵)) (ψ(0) = 1), n the unit axis;
///   - scale: u = (factor − 1) ψ(ρ) r;
///   - pinch: u = (φ − 2b/ρ³) F r + 3b (rᵀ F r)/ρ⁵ r, φ = 1/ρ³ + 3ε²/(2ρ⁵), F = ε³ P / (5/2 − 2b)
///            with P the matrix (so ∇u(0) = P).
/// The affine brushes are the paper's locally affine Kelvinlets (the Kelvinlet's gradient
/// contracted with a force matrix), normalised so that ∇u(0) is the brush's matrix: the
/// Jacobian at the centre is I + θ [n]× (twist: the rotation's derivative, not the rotation:
/// steps > 1 approaches it), factor · I (scale, exact for any steps) and I + P (pinch).
/// The Jacobian is analytic everywhere (the chain rule through the steps).
///
/// Cost: a few dozen flops per point and step; applyBatch is parallel and bit-identical to
/// apply() for any thread count. Large brushes can fold space (det J <= 0) with steps = 1;
/// more steps reduce that.
class KelvinletWarp final : public Warp {
 public:
  /// Throws InvalidInput naming the option for: a centre that is not finite or beyond 1e150, a
  /// radius that is not finite and > 0 (any other radius works: the brush is evaluated in units
  /// of it), a Poisson ratio outside [0, 0.5] or NaN, a displacement that is not finite or beyond
  /// 1e150 (so the centre plus it stays finite), a zero
  /// or non-finite axis, a non-finite angle, a factor that is not finite and > 0, a non-finite,
  /// non-symmetric or non-traceless matrix, steps outside 1..10000.
  explicit KelvinletWarp(const KelvinletOptions& options);

  Vec3 apply(const Vec3& x) const override;
  Mat3 jacobian(const Vec3& x) const override;

  const KelvinletOptions& options() const { return options_; }

  /// Archive tag "kelvinlet": every option (brush, centre, radius, Poisson ratio, each brush's
  /// parameters, falloff, steps).
  void save(ArchiveWriter& out) const override;
  /// Rebuilt through the constructor.
  static std::shared_ptr<const KelvinletWarp> load(ArchiveReader& in);

 protected:
  /// 4096 brush evaluations per range: fewer points when there are many steps and scales, so
  /// that a stepped brush on a few thousand points still spreads over every thread.
  std::size_t batchGrain() const override;
  UnmappedPoints applyRange(std::span<const Vec3> in, std::span<Vec3> out, std::size_t begin,
                            std::size_t end) const override;

 private:
  KelvinletOptions options_;
  // Per step: the displacement (grab), the matrix (pinch), the angle (twist), the scale − 1
  // (scale); the forces of each radius are made from them.
  Vec3 edit_{0.0};
  Mat3 editMatrix_{0.0};
  Vec3 axis_{0.0, 0.0, 1.0};
  double amount_ = 0.0;
  double a_ = 1.0, b_ = 0.0;
};

}  // namespace spacewarp
