#include <spacewarp/rig/detail/ffd_rig.h>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/ffd/lattice_coordinates.h>
#include <spacewarp/ffd/lattice_fit.h>

namespace spacewarp::detail {

namespace {

LatticeBasis basisOf(RigReader& r) {
  const std::string name = r.string("basis");
  if (name == "trilinear") return LatticeBasis::Trilinear;
  if (name == "bernstein") return LatticeBasis::Bernstein;
  if (name == "bspline") return LatticeBasis::BSpline;
  r.fail("basis", "'" + name + "' is not one of: trilinear, bernstein, bspline");
}

LatticeOutside outsideOf(RigReader& r) {
  if (!r.has("outside")) return LatticeOutside::Identity;
  const std::string name = r.string("outside");
  if (name == "identity") return LatticeOutside::Identity;
  if (name == "clamp") return LatticeOutside::Clamp;
  if (name == "falloff") return LatticeOutside::Falloff;
  r.fail("outside", "'" + name + "' is not one of: identity, clamp, falloff");
}

LatticeEnds endsOf(RigReader& r, LatticeBasis basis) {
  if (!r.has("ends")) return LatticeEnds::Extrapolate;
  const std::string name = r.string("ends");
  if (basis != LatticeBasis::BSpline)
    r.fail("ends", "applies to the bspline basis only (the other bases have no phantom controls)");
  if (name == "extrapolate") return LatticeEnds::Extrapolate;
  if (name == "repeat") return LatticeEnds::Repeat;
  r.fail("ends", "'" + name + "' is not one of: extrapolate, repeat");
}

std::array<int, 3> resolutionOf(RigReader& r) {
  const nlohmann::json& v = r.array("resolution");
  if (v.size() != 3) r.fail("resolution", "must be an array of 3 integers [l, m, n]");
  std::array<int, 3> n{};
  for (int a = 0; a < 3; ++a) {
    if (!v[a].is_number_integer() || v[a].get<long long>() < 1 || v[a].get<long long>() > 1 << 20)
      r.fail("resolution", "must contain integers between 1 and 1048576");
    n[a] = v[a].get<int>();
  }
  return n;
}

}  // namespace

Rig ffdRig(RigReader& r) {
  LatticeOptions p;
  p.basis = basisOf(r);
  p.origin = r.vec3("origin");
  p.extents = r.vec3("size");
  p.resolution = resolutionOf(r);
  if (r.has("axes")) {
    const std::vector<Vec3> axes = r.points("axes", 3);
    if (axes.size() != 3) r.fail("axes", "must be an array of 3 [x, y, z] directions");
    for (int a = 0; a < 3; ++a) {
      const double length = glm::length(axes[a]);
      if (!(length > 0.0)) r.fail("axes", "must not contain a zero direction");
      p.axes[a] = axes[a] / length;
    }
  }
  p.ends = endsOf(r, p.basis);
  p.outside = outsideOf(r);
  p.falloff = r.number("falloff", p.falloff);
  const Lattice lattice(p);

  std::vector<Vec3> posed;
  const bool hasControls = r.has("controlPoints");
  if (hasControls == r.has("constraints"))
    r.fail(hasControls ? "constraints" : "controlPoints",
           hasControls ? "cannot be combined with 'controlPoints'"
                       : "is missing (or give 'constraints')");
  if (hasControls) {
    posed = r.points("controlPoints");
    if (posed.size() != lattice.controlPointCount())
      r.fail("controlPoints", "has " + std::to_string(posed.size()) + " points, the resolution " +
                                  std::to_string(p.resolution[0]) + " x " +
                                  std::to_string(p.resolution[1]) + " x " +
                                  std::to_string(p.resolution[2]) + " needs " +
                                  std::to_string(lattice.controlPointCount()));
  } else {
    RigReader constraints(r.object("constraints"), r.baseDir(), r.where() + ": constraints");
    constraints.allowOnly({"from", "to"}, "the constraints", "constraints");
    const std::vector<Vec3> from = constraints.points("from");
    const std::vector<Vec3> to = constraints.points("to");
    if (to.size() != from.size())
      constraints.fail("to", "must have as many points as 'from' (" + std::to_string(from.size()) +
                                 "), not " + std::to_string(to.size()));
    constraints.finish();
    LatticeFitOptions options;
    options.progress = r.place().progress;
    options.smoothness = r.number("smoothness", options.smoothness);
    if (!(std::isfinite(options.smoothness) && options.smoothness >= 0.0))
      r.fail("smoothness", "must be finite and >= 0");
    if (r.checking()) return {};  // the fit is the expensive part
    try {
      posed = fitControlPoints(lattice, from, to, options).controlPoints;
    } catch (const SolverError&) {
      // Without smoothing, control points that no constraint reaches are free: the user's
      // choice of key, not a numerical accident.
      if (options.smoothness == 0.0)
        r.fail("smoothness",
               "is 0 and the fit is singular: constraints do not reach every control point "
               "(give a smoothness > 0, or constraints near every control point)");
      throw;
    }
  }
  auto coordinates = std::make_shared<LatticeCoordinates>(lattice);
  return {makeWarp(coordinates, posed), std::move(coordinates)};
}

}  // namespace spacewarp::detail
