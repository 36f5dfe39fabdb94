#include <spacewarp/core/inverse.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include <spacewarp/core/detail/batch.h>
#include <spacewarp/core/detail/power_of_two_scale.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

// Chord steps with a fixed inverse Jacobian (no Jacobian evaluated) while each cuts the residual
// at least fourfold, then damped Newton with the warp's Jacobian, backtracking on the residual.
// `fx` is warp(result.x) and `result.residual` its distance to y on entry.
void newton(const Warp& warp, const Vec3& y, Vec3 fx, const Mat3* chordInverse, double tolerance,
            int maxIterations, InverseResult& result) {
  bool chord = chordInverse != nullptr;
  for (;;) {
    if (result.residual <= tolerance) {
      result.converged = true;
      return;
    }
    if (result.iterations >= maxIterations) return;
    if (chord) {
      const Vec3 candidate = result.x - *chordInverse * (fx - y);
      const Vec3 fc = warp.apply(candidate);
      const double r = glm::length(fc - y);
      if (r <= 0.25 * result.residual) {  // false for NaN
        result.x = candidate;
        fx = fc;
        result.residual = r;
        ++result.iterations;
        continue;
      }
      chord = false;
    }
    const Mat3 j = warp.jacobian(result.x);
    if (isSingularJacobian(j)) return;
    const Vec3 dx = -detail::solveScaled(j, fx - y);  // no overflow for huge J
    // Backtracking: halve the step until the residual decreases; a step cut below 1e-6 of
    // Newton's means the model is useless here (a kink or a fold), which the fallback handles.
    bool accepted = false;
    for (double t = 1.0; t > 1e-6; t *= 0.5) {
      const Vec3 candidate = result.x + t * dx;
      const Vec3 fc = warp.apply(candidate);
      const double r = glm::length(fc - y);
      if (r < result.residual) {  // false for NaN
        result.x = candidate;
        fx = fc;
        result.residual = r;
        accepted = true;
        break;
      }
    }
    ++result.iterations;
    if (!accepted) return;  // stalled: report the best point found
  }
}

// The Jacobian of the warp by central differences of step h (world units): for a warp that is
// only C⁰ it is the Jacobian averaged over a box of edge 2h, so it models the warp over that
// box across kinks, where the Jacobian at a point models it over no distance at all.
Mat3 secantJacobian(const Warp& warp, const Vec3& x, double h) {
  Mat3 j;
  for (int c = 0; c < 3; ++c) {
    Vec3 e(0.0);
    e[c] = h;
    j[c] = (warp.apply(x + e) - warp.apply(x - e)) / (2.0 * h);
  }
  return j;
}

// A step of robustNewton() under way: the point, its image and residual.
struct Iterate {
  Vec3 x{0.0};
  Vec3 fx{0.0};
  double residual = 0.0;
};

// |warp(x) - y| (infinity where it is not finite), with warp(x) in fx.
double residualAt(const Warp& warp, const Vec3& y, const Vec3& x, Vec3& fx) {
  fx = warp.apply(x);
  const double r = glm::length(fx - y);
  return std::isfinite(r) ? r : std::numeric_limits<double>::infinity();
}

// Backtracking along dx from the iterate; true (and the iterate moved) if the residual fell.
bool backtrack(const Warp& warp, const Vec3& y, const Vec3& dx, Iterate& it) {
  for (double t = 1.0; t > 1e-3; t *= 0.5) {
    Vec3 fc;
    const double r = residualAt(warp, y, it.x + t * dx, fc);
    if (r < it.residual) {
      it.x += t * dx;
      it.fx = fc;
      it.residual = r;
      return true;
    }
  }
  return false;
}

// The smallest residual on the step, t in [0, 1], by golden-section search; true (and the
// iterate moved) if it is below the current one. Finds the way into thin layers where the warp
// is steep (between close kinks) that backtracking steps over.
bool goldenSection(const Warp& warp, const Vec3& y, const Vec3& dx, Iterate& it) {
  constexpr double kGolden = 0.6180339887498949;
  double a = 0.0, b = 1.0;
  double t1 = b - kGolden * (b - a), t2 = a + kGolden * (b - a);
  Vec3 f1, f2;
  double r1 = residualAt(warp, y, it.x + t1 * dx, f1), r2 = residualAt(warp, y, it.x + t2 * dx, f2);
  for (int i = 0; i < 40; ++i) {
    if (r1 <= r2) {
      b = t2;
      t2 = t1;
      r2 = r1;
      f2 = f1;
      t1 = b - kGolden * (b - a);
      r1 = residualAt(warp, y, it.x + t1 * dx, f1);
    } else {
      a = t1;
      t1 = t2;
      r1 = r2;
      f1 = f2;
      t2 = a + kGolden * (b - a);
      r2 = residualAt(warp, y, it.x + t2 * dx, f2);
    }
  }
  if (!(std::min(r1, r2) < it.residual)) return false;
  it.x += (r1 <= r2 ? t1 : t2) * dx;
  it.fx = r1 <= r2 ? f1 : f2;
  it.residual = std::min(r1, r2);
  return true;
}

// Newton for warp(x) = y from `seed` that tolerates kinks: each step is tried with the warp's
// Jacobian at x, then with secant Jacobians over boxes of the residual's size and of four times
// that (at most `maxStep`), with backtracking until the residual decreases; when none does, by
// golden-section search along each. Steps are at most `maxStep` long, to stay on this sheet of
// the warp.
InverseResult robustNewton(const Warp& warp, const Vec3& y, const Vec3& seed, double tolerance,
                           double minStep, double maxStep, int maxIterations) {
  InverseResult s;
  Iterate it;
  it.x = seed;
  it.fx = warp.apply(it.x);
  it.residual = glm::length(it.fx - y);
  s.x = it.x;
  s.residual = it.residual;
  if (!std::isfinite(it.residual)) return s;
  for (;;) {
    s.x = it.x;
    s.residual = it.residual;
    if (it.residual <= tolerance) {
      s.converged = true;
      return s;
    }
    if (s.iterations >= maxIterations) return s;
    ++s.iterations;
    bool accepted = false;
    const double h = std::clamp(it.residual, minStep, maxStep);
    // Backtracking first, then golden-section search, each over the three Jacobians.
    for (int pass = 0; pass < 2 && !accepted; ++pass)
      for (int attempt = 0; attempt < 3 && !accepted; ++attempt) {
        const Mat3 j = attempt == 0   ? warp.jacobian(it.x)
                       : attempt == 1 ? secantJacobian(warp, it.x, h)
                                      : secantJacobian(warp, it.x, std::min(4.0 * h, maxStep));
        if (isSingularJacobian(j)) continue;
        Vec3 dx = -detail::solveScaled(j, it.fx - y);
        const double length = glm::length(dx);
        if (length > maxStep) dx *= maxStep / length;
        accepted = pass == 0 ? backtrack(warp, y, dx, it) : goldenSection(warp, y, dx, it);
      }
    if (!accepted) return s;
  }
}

}  // namespace

InverseResult continueInverse(const Warp& warp, const Vec3& y, const InverseAnchor& anchor,
                              const InverseOptions& options) {
  if (!isFinite(y)) throw InvalidInput("inverse: the target point is not finite");
  InverseResult s;
  s.x = anchor.x;
  const Vec3& y0 = anchor.image;
  const double distance = glm::length(y - y0);
  if (!std::isfinite(distance)) return s;
  const double scale = options.lengthScale > 0.0 ? options.lengthScale
                                                 : std::max({maxAbs(y), maxAbs(y - y0), 1e-300});
  const double tolerance = options.tolerance * scale;
  // The longest step: the length scale, else a sixteenth of the path (and never zero).
  const double voxel =
      options.lengthScale > 0.0 ? options.lengthScale : std::max(distance / 16.0, tolerance);
  double at = 0.0;
  const double maxStep = distance > voxel ? voxel / distance : 1.0;
  double step = maxStep;
  const double minStep = 1e-3 * voxel;
  const int budget = 4 * options.maxIterations;
  while (at < 1.0) {
    if (s.iterations >= 8 * budget || step < 1.0 / 1024.0) return s;
    const double next = std::min(1.0, at + step);
    const bool last = next >= 1.0;
    const Vec3 target = last ? y : y0 + next * (y - y0);
    // Intermediate targets need not be hit exactly: they only guide the path.
    const InverseResult part =
        robustNewton(warp, target, s.x, last ? tolerance : 0.05 * voxel, minStep, voxel, budget);
    s.iterations += part.iterations;
    if (part.converged &&
        glm::determinant(secantJacobian(warp, part.x, 1e-2 * voxel)) * anchor.orientation > 0.0) {
      s.x = part.x;
      s.residual = part.residual;
      at = next;
      step = std::min(2.0 * step, maxStep);
    } else {
      step *= 0.5;
    }
  }
  s.converged = true;
  return s;
}

InverseResult inverse(const Warp& warp, const Vec3& y, const InverseOptions& options,
                      const InverseHint& hint) {
  if (!isFinite(y)) throw InvalidInput("inverse: the target point is not finite");
  const std::optional<Vec3> exact = options.closedForm && options.maxIterations > 0
                                        ? warp.exactInverse(y)
                                        : std::optional<Vec3>();
  const bool useExact = exact && isFinite(*exact);
  // warp(y) is needed only for the default seed and scale: callers that give both skip it.
  Vec3 fy(0.0);
  if ((!hint.seed && !useExact) || !(options.lengthScale > 0.0)) fy = warp.apply(y);
  const double scale = options.lengthScale > 0.0 ? options.lengthScale
                                                 : std::max({maxAbs(y), maxAbs(fy - y), 1e-300});
  const double tolerance = options.tolerance * scale;

  InverseResult result;
  Vec3 fx;
  if (useExact || hint.seed) {
    // The closed form is checked like any other point: if rounding left it above the
    // tolerance, Newton finishes from it.
    result.x = useExact ? *exact : *hint.seed;
    fx = warp.apply(result.x);
    result.residual = glm::length(fx - y);
    if (useExact && result.residual <= tolerance) {
      result.converged = true;
      result.closedForm = true;
      return result;
    }
  } else {
    result.x = y - (fy - y);
    fx = warp.apply(result.x);
    result.residual = glm::length(fx - y);
    if (!std::isfinite(result.residual)) {  // the seed left the warp's domain: start from y
      result.x = y;
      fx = fy;
      result.residual = glm::length(fy - y);
    }
  }
  const Vec3 start = result.x;
  if (std::isfinite(result.residual)) {
    newton(warp, y, fx, hint.chordInverse ? &*hint.chordInverse : nullptr, tolerance,
           options.maxIterations, result);
  }
  // Without a caller's seed, y itself is the second: where the displacement turns fast (a large
  // rotation, a lattice whose faces moved) the reflected one can land across a kink or a jump
  // of the warp that Newton cannot cross back, while the warp's Jacobian at y points the way.
  if (!result.converged && !hint.seed && !(start == y)) {
    InverseResult second;
    second.x = y;
    const Vec3 fyAgain = warp.apply(y);
    second.residual = glm::length(fyAgain - y);
    if (std::isfinite(second.residual))
      newton(warp, y, fyAgain, nullptr, tolerance, options.maxIterations, second);
    second.iterations += result.iterations;
    if (second.converged || second.residual < result.residual) {
      result = second;
    } else {
      result.iterations = second.iterations;
    }
  }
  if (result.converged || !options.continuation) return result;

  InverseAnchor anchor;
  if (hint.anchor) {
    anchor = *hint.anchor;
  } else {
    anchor.x = start;
    anchor.image = warp.apply(anchor.x);
    anchor.orientation = glm::determinant(warp.jacobian(anchor.x)) < 0.0 ? -1.0 : 1.0;
  }
  const InverseResult fallback = continueInverse(warp, y, anchor, options);
  result.continuationIterations = fallback.iterations;
  if (fallback.converged) {
    result.x = fallback.x;
    result.residual = fallback.residual;
    result.converged = true;
  }
  return result;
}

void inverseBatch(const Warp& warp, std::span<const Vec3> targets, std::span<InverseResult> results,
                  const InverseOptions& options, const ProgressCallback& progress) {
  detail::requireSameSize("inverseBatch", targets.size(), results.size());
  for (std::size_t i = 0; i < targets.size(); ++i)
    if (!isFinite(targets[i]))
      throw InvalidInput("inverse: point " + std::to_string(i) + " is not finite");
  // A solve costs tens of warp evaluations: small ranges balance points of unequal cost.
  constexpr std::size_t kGrain = 64;
  const std::size_t n = targets.size();
  ProgressTracker tracker(progress, "inverse", n);
  forEachBlock(n, progress ? std::size_t{1} << 14 : 0, tracker,
               [&](std::size_t begin, std::size_t count) {
                 detail::forEachRange(count, kGrain, [&](std::size_t b, std::size_t e) {
                   for (std::size_t i = begin + b; i != begin + e; ++i)
                     results[i] = inverse(warp, targets[i], options);
                   return UnmappedPoints{};
                 });
               });
}

Vec3 transformNormalByInverse(const Mat3& jacobianAtPreimage, const Vec3& n) {
  const Vec3 v = glm::transpose(detail::scaledToUnit(jacobianAtPreimage)) * n;
  const double length = glm::length(v);
  if (!(length > 0.0) || !std::isfinite(length)) return Vec3(0.0);
  return v / length;
}

}  // namespace spacewarp
