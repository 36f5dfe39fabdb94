#include <spacewarp/rig/detail/mls_rig.h>

#include <memory>
#include <string>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/mls.h>

#ifdef SPACEWARP_WITH_OPENVDB
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/volume/inside_distance.h>
#endif

namespace spacewarp::detail {

namespace {

// "distance": "inside": the handles' distances measured inside the "model" file. Returns null
// when only checking (the model is read and checked, the distances are not computed).
std::shared_ptr<const HandleDistances> insideDistances(RigReader& r,
                                                       const std::vector<Vec3>& handles) {
#ifdef SPACEWARP_WITH_OPENVDB
  const std::filesystem::path model = r.path("model");
  InsideDistanceOptions options;
  if (r.has("voxelSize")) {
    options.voxelSize = r.number("voxelSize");
    if (!(options.voxelSize > 0.0)) r.fail("voxelSize", "must be > 0");
  }
  const PolygonSoup soup = readSoup(model);  // IoError naming the file
  try {
    soup.validate();
  } catch (const InvalidInput& e) {
    r.fail("model", model.string() + ": " + e.what());
  }
  if (r.checking()) return nullptr;
  try {
    return std::make_shared<InsideDistances>(soup, handles, options);
  } catch (const InvalidInput& e) {
    // Named by the key at fault: the voxel size (too fine for the memory), a handle (outside
    // the model), or else the model.
    const std::string what = e.what();
    // "InsideDistances: 'voxelSize' 0.001 (...)": the key once, from the reader.
    if (const auto at = what.find("'voxelSize' "); at != std::string::npos)
      r.fail("voxelSize", what.substr(at + 12));
    if (what.find(": handle ") != std::string::npos)
      r.fail("handles", model.string() + ": " + what);
    r.fail("model", model.string() + ": " + what);
  }
#else
  (void)handles;
  r.fail("distance",
         "\"inside\" is not available: spacewarp was built without OpenVDB "
         "(SPACEWARP_WITH_OPENVDB=OFF)");
#endif
}

}  // namespace

Rig mlsRig(RigReader& r) {
  MlsOptions options;
  if (r.has("mode")) {
    try {
      options.mode = mlsModeFromName(r.string("mode"));
    } catch (const InvalidInput& e) {
      r.fail("mode", e.what());
    }
  }
  options.alpha = r.number("alpha", options.alpha);
  if (!(options.alpha > 0.0)) r.fail("alpha", "must be > 0");
  std::vector<Vec3> handles = r.points("handles");
  std::vector<Vec3> targets = r.points("targets");
  if (targets.size() != handles.size()) {
    r.fail("targets", "must have as many points as 'handles' (" + std::to_string(handles.size()) +
                          "), not " + std::to_string(targets.size()));
  }
  const std::string distance = r.has("distance") ? r.string("distance") : "euclidean";
  if (distance == "inside") {
    options.distances = insideDistances(r, handles);
    if (r.checking()) return {};
  } else if (distance != "euclidean") {
    r.fail("distance", "must be \"euclidean\" or \"inside\", not \"" + distance + "\"");
  }
  return {std::make_shared<MlsWarp>(std::move(handles), std::move(targets), options), nullptr};
}

}  // namespace spacewarp::detail
