#include <spacewarp/ffd/lattice.h>

#include <cmath>
#include <cstdint>
#include <string>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/ffd/detail/lattice_basis.h>

namespace spacewarp {

namespace {

const char* const kAxisNames[3] = {"axes[0]", "axes[1]", "axes[2]"};

// The archived basis value of a B-spline lattice with LatticeEnds::Repeat (see save()).
constexpr std::uint32_t kBSplineRepeatValue = 3;

void validate(const LatticeOptions& p) {
  const std::string who = "Lattice: ";
  if (!isFinite(p.origin)) throw InvalidInput(who + "the origin is not finite");
  if (!isFinite(p.extents)) throw InvalidInput(who + "the extents are not finite");
  for (int a = 0; a < 3; ++a) {
    if (!(p.extents[a] > 0.0))
      throw InvalidInput(who + "extent " + std::to_string(a) + " is " +
                         std::to_string(p.extents[a]) + ", it must be positive");
  }
  for (int a = 0; a < 3; ++a) {
    if (!isFinite(p.axes[a])) throw InvalidInput(who + kAxisNames[a] + " is not finite");
    if (!(std::abs(glm::length(p.axes[a]) - 1.0) <= 1e-9))
      throw InvalidInput(who + kAxisNames[a] + " is not a unit vector (length " +
                         std::to_string(glm::length(p.axes[a])) + ")");
  }
  for (int a = 0; a < 3; ++a) {
    for (int b = a + 1; b < 3; ++b) {
      if (!(std::abs(glm::dot(p.axes[a], p.axes[b])) <= 1e-9))
        throw InvalidInput(who + kAxisNames[a] + " and " + kAxisNames[b] +
                           " are not orthogonal (the axes must be orthonormal)");
    }
  }
  if (p.ends != LatticeEnds::Extrapolate && p.ends != LatticeEnds::Repeat)
    throw InvalidInput(who + "the ends are neither extrapolate nor repeat");
  if (p.ends == LatticeEnds::Repeat && p.basis != LatticeBasis::BSpline)
    throw InvalidInput(who + "the ends 'repeat' apply to the bspline basis only");
  const int minimum = p.basis == LatticeBasis::BSpline ? 4 : 2;
  double total = 1.0;
  for (int a = 0; a < 3; ++a) {
    const int n = p.resolution[a];
    if (n < minimum) {
      throw InvalidInput(who + "resolution[" + std::to_string(a) + "] is " + std::to_string(n) +
                         ", the " +
                         (p.basis == LatticeBasis::BSpline ? "cubic B-spline basis needs at least 4"
                                                           : "lattice needs at least 2") +
                         " control points per axis");
    }
    if (p.basis == LatticeBasis::Bernstein && n > detail::kMaxBernsteinResolution) {
      throw InvalidInput(who + "resolution[" + std::to_string(a) + "] is " + std::to_string(n) +
                         ", the Bernstein basis allows at most " +
                         std::to_string(detail::kMaxBernsteinResolution) +
                         " control points per axis");
    }
    total *= n;
  }
  if (total > 2147483647.0) throw InvalidInput(who + "more than 2^31 - 1 control points in all");
  if (!std::isfinite(p.falloff) || !(p.falloff > 0.0))
    throw InvalidInput(who + "the falloff distance must be finite and positive");
}

}  // namespace

Lattice::Lattice(const LatticeOptions& params) : params_(params) {
  validate(params_);
  const auto [l, m, n] = params_.resolution;
  detail::checkMemory(double(l) * m * n * sizeof(Vec3),
                      "Lattice: the resolution " + std::to_string(l) + " x " + std::to_string(m) +
                          " x " + std::to_string(n));
  rest_.resize(static_cast<std::size_t>(l) * m * n);
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < l; ++i)
        rest_[index(i, j, k)] =
            toWorld(Vec3(double(i) / (l - 1), double(j) / (m - 1), double(k) / (n - 1)));
}

std::size_t Lattice::index(int i, int j, int k) const {
  const auto [l, m, n] = params_.resolution;
  return static_cast<std::size_t>(i) +
         static_cast<std::size_t>(l) * (static_cast<std::size_t>(j) +
                                        static_cast<std::size_t>(m) * static_cast<std::size_t>(k));
}

double Lattice::diagonal() const { return glm::length(params_.extents); }

Vec3 Lattice::toLocal(const Vec3& x) const {
  const Vec3 d = x - params_.origin;
  return {glm::dot(d, params_.axes[0]) / params_.extents.x,
          glm::dot(d, params_.axes[1]) / params_.extents.y,
          glm::dot(d, params_.axes[2]) / params_.extents.z};
}

Vec3 Lattice::toWorld(const Vec3& uvw) const {
  return params_.origin + (uvw.x * params_.extents.x) * params_.axes[0] +
         (uvw.y * params_.extents.y) * params_.axes[1] +
         (uvw.z * params_.extents.z) * params_.axes[2];
}

std::size_t Lattice::maxNonZeros() const {
  switch (params_.basis) {
    case LatticeBasis::Trilinear:
      return 8;
    case LatticeBasis::BSpline:
      return 64;
    case LatticeBasis::Bernstein:
      break;
  }
  return controlPointCount();
}

std::size_t Lattice::sparseWeights(const Vec3& x, std::span<SparseWeight> out,
                                   std::span<Vec3> gradients) const {
  if (!isFinite(x)) throw InvalidInput("Lattice: the query point is not finite");
  const std::size_t most = maxNonZeros();
  if (out.size() < most || (!gradients.empty() && gradients.size() < most))
    throw InvalidInput("Lattice: the sparse weight output holds fewer than " +
                       std::to_string(most) + " entries");
  const bool wantGradients = !gradients.empty();
  const detail::BoxFrame frame(params_);
  double u[3];
  bool clamped[3];
  double s = 1.0;
  Vec3 gradS(0.0);
  if (!detail::locate(frame, x, u, clamped, s, wantGradients ? &gradS : nullptr)) return 0;

  constexpr int kMax = detail::kMaxBernsteinResolution;
  double w[3][kMax], dw[3][kMax];
  int start[3], count[3];
  for (int a = 0; a < 3; ++a) {
    const int n = params_.resolution[a];
    switch (params_.basis) {
      case LatticeBasis::Trilinear:
        start[a] = detail::trilinearAxis(u[a], n, w[a], dw[a]);
        count[a] = 2;
        break;
      case LatticeBasis::BSpline:
        start[a] = params_.ends == LatticeEnds::Repeat
                       ? detail::bsplineRepeatAxis(u[a], n, w[a], dw[a])
                       : detail::bsplineAxis(u[a], n, w[a], dw[a]);
        count[a] = 4;
        break;
      case LatticeBasis::Bernstein:
        start[a] = detail::bernsteinAxis(u[a], n, w[a], dw[a]);
        count[a] = n;
        break;
    }
    // d/dx of u_a: row_a, or 0 where the point was clamped onto the box.
    if (clamped[a])
      for (int c = 0; c < count[a]; ++c) dw[a][c] = 0.0;
  }
  std::size_t written = 0;
  for (int k = 0; k < count[2]; ++k) {
    for (int j = 0; j < count[1]; ++j) {
      const double wjk = w[1][j] * w[2][k];
      for (int i = 0; i < count[0]; ++i) {
        const double base = w[0][i] * wjk;
        out[written] = {static_cast<std::uint32_t>(index(start[0] + i, start[1] + j, start[2] + k)),
                        s * base};
        if (wantGradients) {
          const Vec3 g = (dw[0][i] * wjk) * frame.row[0] +
                         (w[0][i] * dw[1][j] * w[2][k]) * frame.row[1] +
                         (w[0][i] * w[1][j] * dw[2][k]) * frame.row[2];
          gradients[written] = s * g + base * gradS;
        }
        ++written;
      }
    }
  }
  return written;
}

void Lattice::save(ArchiveWriter& out) const {
  out.vec3(params_.origin);
  for (const Vec3& axis : params_.axes) out.vec3(axis);
  out.vec3(params_.extents);
  for (const int r : params_.resolution) out.i32(r);
  // The ends ride in the basis value (3: B-spline with repeated ends), so that the format stays
  // version 2: archives written before read as extrapolate, and an older build refuses a
  // repeat lattice by that value instead of reading it as another lattice.
  if (params_.ends == LatticeEnds::Repeat)
    out.u32(kBSplineRepeatValue);
  else
    out.enumeration(params_.basis);
  out.enumeration(params_.outside);
  out.f64(params_.falloff);
}

Lattice Lattice::load(ArchiveReader& in) { return Lattice(loadOptions(in)); }

LatticeOptions Lattice::loadOptions(ArchiveReader& in) {
  LatticeOptions params;
  params.origin = in.vec3();
  for (Vec3& axis : params.axes) axis = in.vec3();
  params.extents = in.vec3();
  for (int& r : params.resolution) r = in.i32();
  const std::uint32_t basis = in.enumeration<std::uint32_t>(kBSplineRepeatValue + 1);
  params.basis = basis == kBSplineRepeatValue ? LatticeBasis::BSpline : LatticeBasis(basis);
  params.ends = basis == kBSplineRepeatValue ? LatticeEnds::Repeat : LatticeEnds::Extrapolate;
  params.outside = in.enumeration<LatticeOutside>(3);
  params.falloff = in.f64();
  return params;
}

}  // namespace spacewarp
