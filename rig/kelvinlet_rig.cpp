#include <spacewarp/rig/detail/kelvinlet_rig.h>

#include <cmath>
#include <memory>
#include <string>

#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/kelvinlet.h>

namespace spacewarp::detail {

namespace {

// A row-major 3 × 3 matrix, as GLM (column-major).
Mat3 matrix3(RigReader& r, const std::string& key) {
  const nlohmann::json& rows = r.array(key);
  if (rows.size() != 3) r.fail(key, "must be an array of 3 rows");
  Mat3 m(0.0);
  for (int row = 0; row < 3; ++row) {
    const std::vector<double> v = finiteNumbers(
        rows[std::size_t(row)], 3,
        [&](const std::string& what) { r.fail(key + "[" + std::to_string(row) + "]", what); });
    for (int c = 0; c < 3; ++c) m[c][row] = v[std::size_t(c)];
  }
  return m;
}

}  // namespace

Rig kelvinletRig(RigReader& r) {
  KelvinletOptions o;
  try {
    o.brush = kelvinletBrushFromName(r.string("brush"));
  } catch (const InvalidInput& e) {
    r.fail("brush", e.what());
  }
  o.center = r.vec3("center");
  o.radius = r.number("radius");
  if (!(o.radius > 0.0)) r.fail("radius", "must be > 0");
  o.poisson = r.number("poisson", o.poisson);
  if (!(o.poisson >= 0.0 && o.poisson <= 0.5)) r.fail("poisson", "must be in [0, 0.5]");
  if (r.has("falloff")) {
    try {
      o.falloff = kelvinletFalloffFromName(r.string("falloff"));
    } catch (const InvalidInput& e) {
      r.fail("falloff", e.what());
    }
  }
  const double steps = r.number("steps", 1.0);
  if (!(steps >= 1.0 && steps <= 10000.0) || steps != std::floor(steps))
    r.fail("steps", "must be a whole number in 1..10000");
  o.steps = static_cast<int>(steps);
  switch (o.brush) {
    case KelvinletBrush::Grab:
      o.displacement = r.vec3("displacement");
      break;
    case KelvinletBrush::Twist:
      o.axis = r.vec3("axis");
      if (!(glm::length(o.axis) > 0.0)) r.fail("axis", "must not be zero");
      o.angle = r.number("angle");
      break;
    case KelvinletBrush::Scale:
      o.factor = r.number("factor");
      if (!(o.factor > 0.0)) r.fail("factor", "must be > 0");
      break;
    case KelvinletBrush::Pinch:
      o.matrix = matrix3(r, "matrix");
      break;
  }
  // The remaining checks (a pinch matrix that is not symmetric or traceless) are the
  // library's: their message is given as the key's.
  try {
    return {std::make_shared<KelvinletWarp>(o), nullptr};
  } catch (const InvalidInput& e) {
    const std::string prefix = "KelvinletWarp: matrix ";
    const std::string what = e.what();
    if (what.rfind(prefix, 0) == 0) r.fail("matrix", what.substr(prefix.size()));
    throw;
  }
}

}  // namespace spacewarp::detail
