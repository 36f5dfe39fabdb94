#include <spacewarp/nonlinear/kelvinlet.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/enum_names.h>
#include <spacewarp/core/detail/rotation.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/detail/graph_index.h>

namespace spacewarp {

namespace {

constexpr detail::EnumNames<KelvinletBrush, 4> kBrushNames = {{{KelvinletBrush::Grab, "grab"},
                                                               {KelvinletBrush::Twist, "twist"},
                                                               {KelvinletBrush::Scale, "scale"},
                                                               {KelvinletBrush::Pinch, "pinch"}}};
constexpr detail::EnumNames<KelvinletFalloff, 3> kFalloffNames = {
    {{KelvinletFalloff::Single, "single"},
     {KelvinletFalloff::Bi, "bi"},
     {KelvinletFalloff::Tri, "tri"}}};

}  // namespace

std::string kelvinletBrushName(KelvinletBrush brush) {
  return detail::enumName(kBrushNames, brush);
}

std::string kelvinletFalloffName(KelvinletFalloff falloff) {
  return detail::enumName(kFalloffNames, falloff);
}

KelvinletFalloff kelvinletFalloffFromName(std::string_view name) {
  return detail::enumFromName(kFalloffNames, name, "Kelvinlet falloff");
}

KelvinletBrush kelvinletBrushFromName(std::string_view name) {
  return detail::enumFromName(kBrushNames, name, "Kelvinlet brush");
}

namespace {

[[noreturn]] void fail(const std::string& what) { throw InvalidInput("KelvinletWarp: " + what); }

bool finiteMatrix(const Mat3& m) { return isFinite(m[0]) && isFinite(m[1]) && isFinite(m[2]); }

}  // namespace

KelvinletWarp::KelvinletWarp(const KelvinletOptions& o) : options_(o) {
  // Up to 1e150, so that the centre plus the displacement stays finite.
  if (!isFinite(o.center) || !detail::withinReach(o.center))
    fail("center must be finite and within 1e150");
  if (!std::isfinite(o.radius) || !(o.radius > 0.0)) fail("radius must be finite and > 0");
  if (!(o.poisson >= 0.0 && o.poisson <= 0.5)) fail("poisson must be in [0, 0.5]");
  if (o.steps < 1 || o.steps > 10000)
    fail("steps must be in 1..10000, not " + std::to_string(o.steps));
  const double n = static_cast<double>(o.steps);
  a_ = 1.0;  // 1/(4πμ): a common factor of the force, cancelled by the normalisation
  b_ = a_ / (4.0 * (1.0 - o.poisson));
  switch (o.brush) {
    case KelvinletBrush::Grab:
      if (!isFinite(o.displacement) || !detail::withinReach(o.displacement))
        fail("displacement must be finite and within 1e150");
      edit_ = o.displacement / n;
      break;
    case KelvinletBrush::Twist: {
      // Scaled by its largest component first, so that |axis| neither underflows (1e-300) nor
      // overflows (1e300).
      const double big = maxAbs(o.axis);
      if (!isFinite(o.axis) || !(big > 0.0)) fail("axis must be finite and non-zero");
      if (!std::isfinite(o.angle)) fail("angle must be finite");
      axis_ = glm::normalize(o.axis / big);
      amount_ = o.angle / n;
      break;
    }
    case KelvinletBrush::Scale:
      if (!std::isfinite(o.factor) || !(o.factor > 0.0)) fail("factor must be finite and > 0");
      // factor^(1/n) per step, so that the centre scales by exactly `factor` for any steps.
      amount_ = std::pow(o.factor, 1.0 / n) - 1.0;
      break;
    case KelvinletBrush::Pinch: {
      const Mat3& p = o.matrix;
      if (!finiteMatrix(p)) fail("matrix must be finite");
      double norm2 = 0.0;
      for (int c = 0; c < 3; ++c) norm2 += glm::dot(p[c], p[c]);
      const double tol = 1e-12 * std::sqrt(norm2);
      for (int r = 0; r < 3; ++r)
        for (int c = r + 1; c < 3; ++c)
          if (std::abs(p[c][r] - p[r][c]) > tol) fail("matrix must be symmetric");
      if (std::abs(p[0][0] + p[1][1] + p[2][2]) > tol)
        fail("matrix must be traceless (a pinch changes no volume at the centre)");
      editMatrix_ = p / n;
      break;
    }
  }
}

namespace {

// One step: the displacement u at r = x − c and, if `jac`, its gradient.
struct Step {
  KelvinletBrush brush;
  double eps2, eps3, a, b;
  Vec3 force;
  Mat3 f;
  Vec3 axis;
  double amount;

  Vec3 displacement(const Vec3& r, Mat3* jac) const {
    const double rho2 = glm::dot(r, r) + eps2;
    if (!std::isfinite(rho2)) {  // |r| > 1e154 radii: u < 1e-154 of the edit, below resolution
      if (jac) *jac = Mat3(0.0);
      return Vec3(0.0);
    }
    const double rho = std::sqrt(rho2);
    const double i1 = 1.0 / rho;
    const double i3 = i1 / rho2;
    const double i5 = i3 / rho2;
    switch (brush) {
      case KelvinletBrush::Grab: {
        const double alpha = (a - b) * i1 + 0.5 * a * eps2 * i3;
        const double rf = glm::dot(r, force);
        if (jac) {
          // ∇α = −((a − b)/ρ³ + 3aε²/(2ρ⁵)) r; ∇(b (r·f) r / ρ³) = b(r fᵀ + (r·f) I)/ρ³ −
          // 3b (r·f) r rᵀ/ρ⁵.
          const Vec3 dAlpha = -((a - b) * i3 + 1.5 * a * eps2 * i5) * r;
          *jac = glm::outerProduct(force, dAlpha) + (b * i3) * glm::outerProduct(r, force) +
                 Mat3(b * rf * i3) - (3.0 * b * rf * i5) * glm::outerProduct(r, r);
        }
        return alpha * force + (b * rf * i3) * r;
      }
      case KelvinletBrush::Twist:
      case KelvinletBrush::Scale: {
        const double i7 = i5 / rho2;
        const double psi = 0.4 * eps3 * (i3 + 1.5 * eps2 * i5);
        const Vec3 dPsi = (0.4 * eps3 * (-3.0 * i5 - 7.5 * eps2 * i7)) * r;
        if (brush == KelvinletBrush::Twist) {
          const Vec3 nr = glm::cross(axis, r);
          if (jac) *jac = amount * (psi * detail::crossMatrix(axis) + glm::outerProduct(nr, dPsi));
          return (amount * psi) * nr;
        }
        if (jac) *jac = amount * (Mat3(psi) + glm::outerProduct(r, dPsi));
        return (amount * psi) * r;
      }
      case KelvinletBrush::Pinch: {
        const double i7 = i5 / rho2;
        const double beta = i3 + 1.5 * eps2 * i5 - 2.0 * b * i3;
        const double gamma = 3.0 * b * i5;
        const Vec3 fr = f * r;
        const double rfr = glm::dot(r, fr);
        if (jac) {
          const Vec3 dBeta = ((-3.0 + 6.0 * b) * i5 - 7.5 * eps2 * i7) * r;
          const Vec3 dGamma = (-15.0 * b * i7) * r;
          const Vec3 dRfr = fr + glm::transpose(f) * r;
          *jac = beta * f + glm::outerProduct(fr, dBeta) +
                 gamma * (Mat3(rfr) + glm::outerProduct(r, dRfr)) +
                 glm::outerProduct(rfr * r, dGamma);
        }
        return beta * fr + (gamma * rfr) * r;
      }
    }
    return Vec3(0.0);
  }
};

}  // namespace

namespace {

// The brush of one step: Σ_j c_j û_j over its scales, û_j the normalised brush of radius ε_j.
// The normalised brushes share their value and gradient at the centre and Σ c_j = 1, so the
// combination keeps them; the c_j cancel the far field's leading terms (de Goes & James' multi-
// scale extrapolation: Σ w_j = 0 for "bi", also Σ w_j ε_j² = 0 for "tri", with c_j ∝ w_j N_j,
// N_j the unnormalised brush's centre value, ∝ 1/ε_j (grab) or 1/ε_j³ (affine brushes)).
// The steps are evaluated in units of ε (radii 1, 2, 4 at r / ε), so that any finite radius
// works (ε³ and 1/ρ⁵ overflow for radii beyond ~1e60 or below ~1e-60 in world units): the grab's
// displacement does not depend on ε at that scale, the affine brushes' is ε times it.
struct Brush {
  Step scale[3];
  double c[3] = {1.0, 0.0, 0.0};
  int count = 1;
  double eps = 1.0;
  bool grab = true;

  Vec3 displacement(const Vec3& r, Mat3* jac) const {
    const Vec3 unit = r / eps;
    Vec3 u(0.0);
    if (count == 1) {
      u = scale[0].displacement(unit, jac);
    } else {
      if (jac) *jac = Mat3(0.0);
      for (int j = 0; j < count; ++j) {
        Mat3 jj(0.0);
        u += c[j] * scale[j].displacement(unit, jac ? &jj : nullptr);
        if (jac) *jac += c[j] * jj;
      }
    }
    if (grab) {
      if (jac) *jac /= eps;
      return u;
    }
    return eps * u;
  }
};

Brush brushOf(const KelvinletOptions& o, const Vec3& edit, const Mat3& editMatrix, const Vec3& axis,
              double amount, double a, double b) {
  Brush brush;
  brush.eps = o.radius;
  brush.grab = o.brush == KelvinletBrush::Grab;
  const double eps = 1.0;
  double radii[3] = {eps, 2.0 * eps, 4.0 * eps};
  double w[3] = {1.0, 0.0, 0.0};
  if (o.falloff == KelvinletFalloff::Bi) {
    brush.count = 2;
    w[1] = -1.0;
  } else if (o.falloff == KelvinletFalloff::Tri) {
    brush.count = 3;
    const double e1 = radii[0] * radii[0], e2 = radii[1] * radii[1], e3 = radii[2] * radii[2];
    w[1] = -(e3 - e1) / (e3 - e2);
    w[2] = (e2 - e1) / (e3 - e2);
  }
  const int k = o.brush == KelvinletBrush::Grab ? 1 : 3;
  double total = 0.0;
  for (int j = 0; j < brush.count; ++j) {
    const double e = radii[j];
    Step& s = brush.scale[j];
    s = {o.brush,
         e * e,
         e * e * e,
         a,
         b,
         (2.0 * e / (3.0 * a - 2.0 * b)) * edit,
         (e * e * e / (2.5 * a - 2.0 * b)) * editMatrix,
         axis,
         amount};
    brush.c[j] = w[j] / std::pow(e / eps, k);
    total += brush.c[j];
  }
  for (int j = 0; j < brush.count; ++j) brush.c[j] /= total;
  return brush;
}

// The grab brush's centre follows its edit: step k is centred at c + k f_total/steps.
inline Vec3 centerOf(const KelvinletOptions& o, int k) {
  if (o.brush != KelvinletBrush::Grab || k == 0) return o.center;
  return o.center + (static_cast<double>(k) / static_cast<double>(o.steps)) * o.displacement;
}

}  // namespace

Vec3 KelvinletWarp::apply(const Vec3& x) const {
  const Brush step = brushOf(options_, edit_, editMatrix_, axis_, amount_, a_, b_);
  Vec3 y = x;
  for (int k = 0; k < options_.steps; ++k)
    y += step.displacement(y - centerOf(options_, k), nullptr);
  return y;
}

std::size_t KelvinletWarp::batchGrain() const {
  const int scales = options_.falloff == KelvinletFalloff::Single ? 1
                     : options_.falloff == KelvinletFalloff::Bi   ? 2
                                                                  : 3;
  // Depends only on the options: the ranges, hence the result, not on the thread count.
  return std::max<std::size_t>(4, 4096 / std::size_t(options_.steps * scales));
}

UnmappedPoints KelvinletWarp::applyRange(std::span<const Vec3> in, std::span<Vec3> out,
                                         std::size_t begin, std::size_t end) const {
  const Brush step = brushOf(options_, edit_, editMatrix_, axis_, amount_, a_, b_);
  for (std::size_t i = begin; i != end; ++i) {
    Vec3 y = in[i];
    for (int k = 0; k < options_.steps; ++k)
      y += step.displacement(y - centerOf(options_, k), nullptr);
    out[i] = y;
  }
  return {};
}

Mat3 KelvinletWarp::jacobian(const Vec3& x) const {
  const Brush step = brushOf(options_, edit_, editMatrix_, axis_, amount_, a_, b_);
  Vec3 y = x;
  Mat3 j(1.0);
  for (int k = 0; k < options_.steps; ++k) {
    Mat3 ju(0.0);
    y += step.displacement(y - centerOf(options_, k), &ju);
    j = (Mat3(1.0) + ju) * j;
  }
  return j;
}

void KelvinletWarp::save(ArchiveWriter& out) const {
  const KelvinletOptions& o = options_;
  out.tag("kelvinlet");
  out.enumeration(o.brush);
  out.vec3(o.center);
  out.f64(o.radius);
  out.f64(o.poisson);
  out.vec3(o.displacement);
  out.vec3(o.axis);
  out.f64(o.angle);
  out.f64(o.factor);
  out.mat3(o.matrix);
  out.enumeration(o.falloff);
  out.i32(o.steps);
}

std::shared_ptr<const KelvinletWarp> KelvinletWarp::load(ArchiveReader& in) {
  KelvinletOptions o;
  o.brush = in.enumeration<KelvinletBrush>(kBrushNames.size());
  o.center = in.vec3();
  o.radius = in.f64();
  o.poisson = in.f64();
  o.displacement = in.vec3();
  o.axis = in.vec3();
  o.angle = in.f64();
  o.factor = in.f64();
  o.matrix = in.mat3();
  o.falloff = in.enumeration<KelvinletFalloff>(kFalloffNames.size());
  o.steps = in.i32();
  return std::make_shared<const KelvinletWarp>(o);
}

}  // namespace spacewarp
