#pragma once
// The inverse of a warp at a point: x with warp(x) = y. One solver for every caller (points,
// the CLI, volumes): seeded damped Newton, optionally preceded by chord steps with a fixed
// Jacobian, and a continuation fallback for warps that are only C⁰ (kinks stall Newton).

#include <optional>
#include <span>

#include <spacewarp/core/math.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/core/warp.h>

namespace spacewarp {

/// Options of inverse().
struct InverseOptions {
  /// Newton (and chord) iterations at most in the first solve. The continuation fallback may
  /// take up to 4 times this per continuation step and 32 times this in all. Default 50.
  int maxIterations = 50;
  /// Converged when |warp(x) - y| <= tolerance * scale, where scale is `lengthScale` if it is
  /// positive, and otherwise max(|y|_inf, |warp(y) - y|_inf, 1e-300). Default 1e-12.
  double tolerance = 1e-12;
  /// World-unit length that the tolerance is relative to; 0 (the default) means "derive from
  /// y". It is also the longest step of the continuation fallback: its path advances by at
  /// most this much per step (without it, a sixteenth of the path's length).
  double lengthScale = 0.0;
  /// Whether a point that Newton could not invert gets the continuation fallback (see
  /// continueInverse()). Default on.
  bool continuation = true;
  /// Whether the warp's closed-form inverse (Warp::exactInverse()) is used where it has one:
  /// the result is then that point, reported converged (with `closedForm` set) with its
  /// residual measured and no iterations, as long as that residual meets the tolerance; if it
  /// does not, the closed form seeds Newton. Default on. Not used when maxIterations is 0 (the
  /// seed alone is evaluated).
  bool closedForm = true;
};

/// What inverse() found. `converged` is false when the iterations ran out, the Jacobian was
/// singular, or the residual stopped decreasing (and the fallback failed too); `x` is then the
/// best point found by the first solve.
struct InverseResult {
  Vec3 x{0.0};
  bool converged = false;
  int iterations = 0;  ///< Chord and Newton steps of the first solve (both seeds' steps).
  /// Whether x is the warp's closed-form inverse (Warp::exactInverse()), with no iteration.
  bool closedForm = false;
  /// Newton steps of the continuation fallback (0 when it did not run).
  int continuationIterations = 0;
  double residual = 0.0;  ///< |warp(x) - y| in world units.
};

/// A point whose image is known, from which continuation walks to the target along the
/// straight segment between the images.
struct InverseAnchor {
  Vec3 x{0.0};      ///< World units.
  Vec3 image{0.0};  ///< warp(x), or the caller's estimate of it, world units.
  /// The sign (+1 or -1) that det J keeps along the path: a step whose preimage has the other
  /// sign has crossed a fold and is refused.
  double orientation = 1.0;
};

/// Optional knowledge of the caller that makes the solve cheaper or more reliable.
struct InverseHint {
  /// Where Newton starts (world units). Default: the reflected displacement y - (warp(y) - y),
  /// or y itself when the warp is not finite there; where Newton from it fails, Newton from y
  /// is tried too. A seed given here is the only one, and where the warp is not finite there
  /// the first solve fails.
  std::optional<Vec3> seed;
  /// The inverse of a fixed Jacobian near the solution (e.g. of the seed's neighbourhood): the
  /// first steps are chord steps x -= chordInverse (warp(x) - y), no Jacobian evaluated, for
  /// as long as each reduces the residual at least fourfold; Newton follows.
  std::optional<Mat3> chordInverse;
  /// Where the continuation fallback starts. Default: the seed, its image and the sign of
  /// det J there.
  std::optional<InverseAnchor> anchor;
};

/// Finds x with warp(x) = y: the warp's closed form if it has one (options.closedForm), else damped
/// Newton (backtracking on the residual) from the hint's seed (after chord steps if the hint has a
/// chord matrix) — without a seed from the hint, from the default seed and then, if that fails,
/// from y itself —, then, if that fails and options.continuation is on, continueInverse() from the
/// hint's anchor. Never throws for non-convergence: it reports it. Throws InvalidInput if y is not
/// finite.
InverseResult inverse(const Warp& warp, const Vec3& y, const InverseOptions& options = {},
                      const InverseHint& hint = {});

/// results[i] = inverse(warp, targets[i], options) for every i, in parallel (TBB), each from the
/// default seed. The ranges depend only on the number of points, so the results do not depend on
/// the number of threads. Reports the stage "inverse" to `progress`; a cancel throws Cancelled.
/// Throws InvalidInput if the spans differ in size or a target is not finite (naming its index).
void inverseBatch(const Warp& warp, std::span<const Vec3> targets, std::span<InverseResult> results,
                  const InverseOptions& options = {}, const ProgressCallback& progress = {});

/// The normal n at y = warp(x) carried through the warp's inverse, given the warp's Jacobian J
/// at the preimage x: J^T n normalised (the inverse's Jacobian at y is J^-1, and J^-1's
/// inverse transpose is J^T), a zero vector where that vanishes (never NaN). J is first scaled
/// by a power of two, as in transformNormal(), so entries near 1e300 or 1e-300 give it too.
Vec3 transformNormalByInverse(const Mat3& jacobianAtPreimage, const Vec3& n);

/// The continuation fallback on its own: from the anchor along the segment from its image to y
/// in steps of at most options.lengthScale (a sixteenth of the segment if 0), each solved by a
/// Newton that tolerates kinks (the warp's Jacobian, then secant Jacobians over boxes of the
/// residual's size; backtracking, then golden-section line search) from the previous preimage,
/// never stepping further than a step length and refusing preimages across a fold (det J of the
/// wrong sign); a step that fails is halved, and the walk gives up below 1/1024 of the path.
/// Intermediate targets are met to 0.05 step lengths, the last to the options' tolerance.
/// The result's `iterations` are the Newton steps taken. Deterministic: it depends on y, the
/// anchor and the options only. Throws InvalidInput if y is not finite.
InverseResult continueInverse(const Warp& warp, const Vec3& y, const InverseAnchor& anchor,
                              const InverseOptions& options = {});

}  // namespace spacewarp
