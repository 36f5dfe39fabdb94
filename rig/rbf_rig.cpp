#include <spacewarp/rig/detail/rbf_rig.h>

#include <atomic>
#include <cstdio>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/rbf/detail/rbf_system.h>
#include <spacewarp/rbf/rbf_coordinates.h>
#include <spacewarp/rbf/rbf_warp.h>

namespace spacewarp::detail {

namespace {

// RbfCoordinates built on first use: their construction (O(n³), n right-hand sides) is only
// paid by `spacewarp weights`, not by every `deform` with an RBF rig.
class LazyRbfCoordinates final : public Coordinates {
 public:
  LazyRbfCoordinates(std::vector<Vec3> centers, std::vector<Vec3> fixed, const RbfOptions& options,
                     std::string where)
      : centers_(std::move(centers)),
        fixed_(std::move(fixed)),
        options_(options),
        where_(std::move(where)) {}

  std::size_t controlPointCount() const override { return centers_.size(); }
  std::span<const Vec3> restControlPoints() const override { return centers_; }
  void weights(const Vec3& x, std::span<double> row) const override { get().weights(x, row); }
  bool weightGradients(const Vec3& x, std::span<Vec3> out) const override {
    return get().weightGradients(x, out);
  }

  // Archive: tag "lazy-rbf-coordinates", what the fit needs, and the fit itself once it has
  // been made (so a loaded copy fits no more often than the original would).
  void save(ArchiveWriter& out) const override {
    out.tag("lazy-rbf-coordinates");
    out.string(where_);
    writeRbfOptions(out, options_);
    out.vec3s(centers_);
    out.vec3s(fixed_);
    const bool built = built_.load();
    out.boolean(built);
    if (built) out.coordinates(*coordinates_);
  }

  static std::shared_ptr<const Coordinates> load(ArchiveReader& in) {
    std::string where = in.string();
    const RbfOptions options = readRbfOptions(in);
    std::vector<Vec3> centers = in.vec3s();
    std::vector<Vec3> fixed = in.vec3s();
    auto lazy = std::make_shared<LazyRbfCoordinates>(std::move(centers), std::move(fixed), options,
                                                     std::move(where));
    if (in.boolean()) {
      auto fit = std::dynamic_pointer_cast<const RbfCoordinates>(in.coordinates());
      if (!fit || fit->controlPointCount() != lazy->controlPointCount())
        in.fail("lazy RBF coordinates whose fit is not RBF coordinates of their centers");
      std::call_once(lazy->once_, [&] { lazy->coordinates_ = std::move(fit); });
      lazy->built_ = true;
    }
    return lazy;
  }

 protected:
  UnmappedPoints weightsRange(std::span<const Vec3> points, std::span<double> rows,
                              std::size_t begin, std::size_t end) const override {
    const std::size_t m = columnCount();
    get().weightsBatch(points.subspan(begin, end - begin),
                       rows.subspan(begin * m, (end - begin) * m));
    return {};
  }

 private:
  const RbfCoordinates& get() const {
    // Built after the rig was read: its errors still name the rig.
    std::call_once(once_, [this] {
      coordinates_ = namingFile(where_, [this] {
        return std::make_shared<const RbfCoordinates>(centers_, fixed_, options_);
      });
      built_ = true;
    });
    return *coordinates_;
  }

  std::vector<Vec3> centers_, fixed_;
  RbfOptions options_;
  std::string where_;
  mutable std::once_flag once_;
  mutable std::shared_ptr<const RbfCoordinates> coordinates_;
  mutable std::atomic<bool> built_{false};
};

}  // namespace

std::shared_ptr<const Coordinates> loadLazyRbfCoordinates(ArchiveReader& in) {
  return LazyRbfCoordinates::load(in);
}

Rig rbfRig(RigReader& r) {
  RbfOptions options;
  if (r.has("kernel")) {
    try {
      options.kernel = rbfKernelFromName(r.string("kernel"));
    } catch (const InvalidInput& e) {
      r.fail("kernel", e.what());
    }
  }
  const std::vector<Vec3> centers = r.points("centers");
  const std::vector<Vec3> targets = r.points("targets");
  if (targets.size() != centers.size()) {
    r.fail("targets", "must have as many points as 'centers' (" + std::to_string(centers.size()) +
                          "), not " + std::to_string(targets.size()));
  }
  std::vector<Vec3> fixed;
  if (r.has("fixed")) {
    fixed = r.points("fixed", 0);
  }
  options.smoothing = r.number("smoothing", options.smoothing);
  options.progress = r.place().progress;
  if (options.smoothing < 0.0) r.fail("smoothing", "must be >= 0");
  const bool scaled =
      options.kernel == RbfKernel::Gaussian || options.kernel == RbfKernel::InverseMultiquadric;
  if (r.has("scale") && !scaled)
    r.fail("scale", "applies to the gaussian and inverse-multiquadric kernels only");
  if (r.has("radius") && options.kernel != RbfKernel::WendlandC2)
    r.fail("radius", "applies to the wendland kernel only");
  const bool defaultScale = !r.has("scale");
  options.scale = r.number("scale", options.scale);
  options.radius = r.number("radius", options.radius);
  if (!(options.scale > 0.0)) r.fail("scale", "must be > 0");
  if (!(options.radius > 0.0)) r.fail("radius", "must be > 0");
  if (!(options.radius >= kMinRbfScale && options.radius <= kMaxRbfScale))
    r.fail("radius", "must be within [1e-150, 1e150]");
  // A scale that does not suit the centers gives NaN or a singular fit: say so here, naming
  // the key, rather than blame the input for the non-finite points it makes.
  std::vector<Vec3> all = centers;
  all.insert(all.end(), fixed.begin(), fixed.end());
  if (const std::string problem = rbfScaleProblem(options, all); !problem.empty()) {
    char value[32];
    std::snprintf(value, sizeof value, "%.3g", options.scale);
    r.fail("scale", value + std::string(defaultScale ? " (the default) " : " ") + problem);
  }
  // The warp's dense system (RbfWarp checks it too, without the key's name); in `info` too,
  // which refuses what deform would.
  checkMemory(RbfSystem::memoryEstimate(centers.size() + fixed.size()),
              "'centers' (" + std::to_string(centers.size()) + " centers" +
                  (fixed.empty() ? "" : " and " + std::to_string(fixed.size()) + " fixed") + ")");
  if (r.checking()) {
    RbfWarp::check(centers, targets, fixed, options);  // what the fit would refuse, without it
    return {};
  }
  Rig rig;
  rig.warp = std::make_shared<RbfWarp>(centers, targets, fixed, options);
  rig.coordinates = std::make_shared<LazyRbfCoordinates>(centers, fixed, options, r.where());
  return rig;
}

}  // namespace spacewarp::detail
