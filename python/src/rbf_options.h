#pragma once
// The keyword arguments that Rbf and RbfWarp share, as the library's RbfOptions.

#include <string>

#include <spacewarp/rbf/kernels.h>

namespace spacewarp::python {

/// RbfOptions from the keywords kernel (a name of rbfKernelNames()), scale, radius, smoothing,
/// and the call's progress callback.
inline RbfOptions rbfOptions(const std::string& kernel, double scale, double radius,
                             double smoothing, const ProgressCallback& progress) {
  RbfOptions options;
  options.kernel = rbfKernelFromName(kernel);
  options.scale = scale;
  options.radius = radius;
  options.smoothing = smoothing;
  options.progress = progress;
  return options;
}

}  // namespace spacewarp::python
