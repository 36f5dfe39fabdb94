#include <spacewarp/rig/detail/idw_rig.h>

#include <memory>
#include <string>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/shepard.h>

namespace spacewarp::detail {

Rig idwRig(RigReader& r) {
  ShepardOptions options;
  options.power = r.number("power", options.power);
  if (!(options.power > 0.0)) r.fail("power", "must be > 0");
  if (r.has("radius")) {
    options.radius = r.number("radius");
    if (!(options.radius > 0.0)) r.fail("radius", "must be > 0");
  }
  std::vector<Vec3> handles = r.points("handles");
  const std::vector<Vec3> targets = r.points("targets");
  if (targets.size() != handles.size()) {
    r.fail("targets", "must have as many points as 'handles' (" + std::to_string(handles.size()) +
                          "), not " + std::to_string(targets.size()));
  }
  auto coordinates = std::make_shared<const ShepardCoordinates>(std::move(handles), options);
  return {makeWarp(coordinates, targets), coordinates};
}

}  // namespace spacewarp::detail
