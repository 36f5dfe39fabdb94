#include <spacewarp/rbf/kernels.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

struct KernelName {
  RbfKernel kernel;
  const char* name;
};

constexpr KernelName kNames[] = {
    {RbfKernel::Triharmonic, "triharmonic"},
    {RbfKernel::Biharmonic, "biharmonic"},
    {RbfKernel::ThinPlate, "thin-plate"},
    {RbfKernel::Gaussian, "gaussian"},
    {RbfKernel::InverseMultiquadric, "inverse-multiquadric"},
    {RbfKernel::WendlandC2, "wendland"},
};

constexpr const char* kOutOfRange =
    "is outside [1e-150, 1e150], where the kernel's squares and their reciprocals are finite";

// "1e-200", "0.25": for messages.
std::string shortNumber(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", value);
  return text;
}

}  // namespace

std::string rbfKernelName(RbfKernel kernel) {
  for (const KernelName& k : kNames)
    if (k.kernel == kernel) return k.name;
  throw InvalidInput("unknown RBF kernel " + std::to_string(static_cast<int>(kernel)));
}

std::vector<std::string> rbfKernelNames() {
  std::vector<std::string> names;
  for (const KernelName& k : kNames) names.emplace_back(k.name);
  return names;
}

RbfKernel rbfKernelFromName(std::string_view name) {
  std::string known;
  for (const KernelName& k : kNames) {
    if (name == k.name) return k.kernel;
    known += known.empty() ? "" : ", ";
    known += k.name;
  }
  std::string message = "unknown RBF kernel '";
  message += name;
  message += "' (one of: " + known + ")";
  throw InvalidInput(message);
}

double rbfKernelValue(const RbfOptions& o, double r) {
  switch (o.kernel) {
    case RbfKernel::Triharmonic:
      return r * r * r;
    case RbfKernel::Biharmonic:
      return r;
    case RbfKernel::ThinPlate:
      return r > 0.0 ? r * r * std::log(r) : 0.0;
    case RbfKernel::Gaussian: {
      const double s = r / o.scale;
      return std::exp(-s * s);
    }
    case RbfKernel::InverseMultiquadric:
      return 1.0 / std::sqrt(r * r + o.scale * o.scale);
    case RbfKernel::WendlandC2: {
      const double s = r / o.radius;
      if (s >= 1.0) return 0.0;
      const double t = 1.0 - s;
      return (t * t) * (t * t) * (4.0 * s + 1.0);
    }
  }
  return 0.0;
}

double rbfKernelSlopeOverR(const RbfOptions& o, double r) {
  switch (o.kernel) {
    case RbfKernel::Triharmonic:
      return 3.0 * r;
    case RbfKernel::Biharmonic:
      return r > 0.0 ? 1.0 / r : 0.0;
    case RbfKernel::ThinPlate:
      return r > 0.0 ? 2.0 * std::log(r) + 1.0 : 0.0;
    case RbfKernel::Gaussian: {
      const double s = r / o.scale;
      return -2.0 / (o.scale * o.scale) * std::exp(-s * s);
    }
    case RbfKernel::InverseMultiquadric: {
      const double q = 1.0 / std::sqrt(r * r + o.scale * o.scale);
      return -q * q * q;
    }
    case RbfKernel::WendlandC2: {
      const double s = r / o.radius;
      if (s >= 1.0) return 0.0;
      const double t = 1.0 - s;
      return -20.0 * t * t * t / (o.radius * o.radius);
    }
  }
  return 0.0;
}

void validateRbfOptions(const std::string& who, const RbfOptions& o) {
  auto fail = [&](const std::string& what) { throw InvalidInput(who + ": " + what); };
  bool known = false;
  for (const KernelName& k : kNames) known = known || k.kernel == o.kernel;
  if (!known) fail("unknown kernel " + std::to_string(static_cast<int>(o.kernel)));
  if (!(std::isfinite(o.scale) && o.scale > 0.0))
    fail("the kernel scale must be finite and > 0, not " + shortNumber(o.scale));
  if (!(o.scale >= kMinRbfScale && o.scale <= kMaxRbfScale))
    fail("the kernel scale " + shortNumber(o.scale) + " " + kOutOfRange);
  if (!(std::isfinite(o.radius) && o.radius > 0.0))
    fail("the support radius must be finite and > 0, not " + shortNumber(o.radius));
  if (!(o.radius >= kMinRbfScale && o.radius <= kMaxRbfScale))
    fail("the support radius " + shortNumber(o.radius) + " " + kOutOfRange);
  if (!(std::isfinite(o.smoothing) && o.smoothing >= 0.0))
    fail("the smoothing must be finite and >= 0, not " + shortNumber(o.smoothing));
  if (!(std::isfinite(o.duplicateTolerance) && o.duplicateTolerance >= 0.0))
    fail("the duplicate tolerance must be finite and >= 0");
}

}  // namespace spacewarp

namespace spacewarp {

std::string rbfScaleProblem(const RbfOptions& o, std::span<const Vec3> centers) {
  if (o.kernel != RbfKernel::Gaussian && o.kernel != RbfKernel::InverseMultiquadric) return {};
  if (!(std::isfinite(o.scale) && o.scale > 0.0)) return "must be finite and > 0";
  if (!(o.scale >= kMinRbfScale && o.scale <= kMaxRbfScale)) return kOutOfRange;
  if (centers.size() < 2) return {};
  Vec3 lo = centers[0], hi = centers[0];
  for (const Vec3& p : centers) lo = glm::min(lo, p), hi = glm::max(hi, p);
  const double extent = glm::length(hi - lo);
  if (!(extent > 0.0) || !std::isfinite(extent)) return {};
  // Too large: r²/ε² below half an ulp of 1 for every r up to the extent.
  const double spread = extent / o.scale;
  if (spread * spread < std::numeric_limits<double>::epsilon())
    return "is too large for centers spanning " + shortNumber(extent) +
           ": the kernel has the same value between any two of them in double precision, so "
           "the fit is singular; give about the centers' spacing";
  if (o.kernel != RbfKernel::Gaussian) return {};
  // Too small: the closest two distinct centers (a sweep along x) are beyond the underflow of
  // exp(-(r/ε)²), at (r/ε)² > 708.
  std::vector<std::size_t> order(centers.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t a, std::size_t b) { return centers[a].x < centers[b].x; });
  const double same = o.duplicateTolerance * extent;
  double closest = std::numeric_limits<double>::infinity();
  for (std::size_t s = 0; s < order.size(); ++s) {
    const Vec3& a = centers[order[s]];
    for (std::size_t t = s + 1; t < order.size() && centers[order[t]].x - a.x < closest; ++t) {
      const double d = glm::length(centers[order[t]] - a);
      if (d > same) closest = std::min(closest, d);
    }
  }
  if (!std::isfinite(closest)) return {};
  const double ratio = closest / o.scale;
  if (!(ratio * ratio <= 708.0))
    return "is too small for centers " + shortNumber(closest) +
           " apart (the closest two): exp(-(r/scale)^2) underflows to 0 between any two "
           "centers, so each moves alone; give about the centers' spacing";
  return {};
}

void writeRbfOptions(ArchiveWriter& out, const RbfOptions& options) {
  out.enumeration(options.kernel);
  out.f64(options.scale);
  out.f64(options.radius);
  out.f64(options.smoothing);
  out.f64(options.duplicateTolerance);
}

RbfOptions readRbfOptions(ArchiveReader& in) {
  RbfOptions options;
  options.kernel = in.enumeration<RbfKernel>(6);
  options.scale = in.f64();
  options.radius = in.f64();
  options.smoothing = in.f64();
  options.duplicateTolerance = in.f64();
  validateRbfOptions("warp archive: RBF options", options);
  return options;
}

}  // namespace spacewarp
