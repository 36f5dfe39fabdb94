#include <spacewarp/rbf/kernels.h>

#include <cmath>

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
    fail("the kernel scale must be finite and > 0, not " + std::to_string(o.scale));
  if (!(std::isfinite(o.radius) && o.radius > 0.0))
    fail("the support radius must be finite and > 0, not " + std::to_string(o.radius));
  if (!(std::isfinite(o.smoothing) && o.smoothing >= 0.0))
    fail("the smoothing must be finite and >= 0, not " + std::to_string(o.smoothing));
  if (!(std::isfinite(o.duplicateTolerance) && o.duplicateTolerance >= 0.0))
    fail("the duplicate tolerance must be finite and >= 0");
}

}  // namespace spacewarp
