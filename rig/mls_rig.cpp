#include <spacewarp/rig/detail/mls_rig.h>

#include <memory>
#include <string>
#include <vector>

#include <spacewarp/core/errors.h>
#include <spacewarp/nonlinear/mls.h>

namespace spacewarp::detail {

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
  return {std::make_shared<MlsWarp>(std::move(handles), std::move(targets), options), nullptr};
}

}  // namespace spacewarp::detail
