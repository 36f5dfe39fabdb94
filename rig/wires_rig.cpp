#include <spacewarp/rig/detail/wires_rig.h>

#include <memory>
#include <string>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/wires.h>

namespace spacewarp::detail {

namespace {

// One wire object, read with a reader of its own so that its errors name it ("wires[1]").
Wire readWire(const nlohmann::json& object, const RigReader& r, std::size_t index) {
  if (!object.is_object()) {
    // Appended piece by piece (GCC 12 warns falsely, -Wrestrict, about "[" + a string).
    std::string what = "[";
    what += std::to_string(index);
    what += "] must be a JSON object (a wire)";
    r.fail("wires", what);
  }
  RigReader w(object, r.baseDir(), r.where() + ": wires[" + std::to_string(index) + "]");
  w.allowOnly({"rest", "deformed", "radius", "innerRadius", "scale", "dropoff", "curve"}, "a wire",
              "a wire");
  Wire wire;
  // Enumerated names first: a wrong name is the likelier mistake than wrong numbers.
  if (w.has("curve")) {
    // The string read outside the try: its own type error already names the place.
    const std::string name = w.string("curve");
    try {
      wire.curve = wireCurveFromName(name);
    } catch (const InvalidInput& e) {
      w.fail("curve", e.what());
    }
  }
  if (w.has("dropoff")) {
    // The string read outside the try: its own type error already names the place.
    const std::string name = w.string("dropoff");
    try {
      wire.dropoff = wireDropoffFromName(name);
    } catch (const InvalidInput& e) {
      w.fail("dropoff", e.what());
    }
  }
  wire.rest = w.points("rest", 2);
  wire.deformed = w.points("deformed", 2);
  if (wire.deformed.size() != wire.rest.size()) {
    w.fail("deformed", "must have as many points as 'rest' (" + std::to_string(wire.rest.size()) +
                           "), not " + std::to_string(wire.deformed.size()));
  }
  wire.radius = w.number("radius");
  if (!(wire.radius > 0.0)) w.fail("radius", "must be > 0");
  wire.innerRadius = w.number("innerRadius", wire.innerRadius);
  if (!(wire.innerRadius >= 0.0 && wire.innerRadius < wire.radius))
    w.fail("innerRadius", "must be >= 0 and < 'radius'");
  wire.scale = w.number("scale", wire.scale);
  if (!(wire.scale > 0.0)) w.fail("scale", "must be > 0");
  w.finish();
  return wire;
}

}  // namespace

Rig wiresRig(RigReader& r) {
  WiresOptions options;
  options.locality = r.number("locality", options.locality);
  if (!(options.locality >= 0.0)) r.fail("locality", "must be >= 0");
  const nlohmann::json& array = r.array("wires");
  std::vector<Wire> wires;
  for (std::size_t i = 0; i < array.size(); ++i) wires.push_back(readWire(array[i], r, i));
  // Cheap (a grid per wire), so built when only checking too: it validates the curves.
  auto warp = std::make_shared<WiresWarp>(std::move(wires), options);
  if (r.checking()) return {};
  return {std::move(warp), nullptr};
}

}  // namespace spacewarp::detail
