#pragma once
// The elementary functions of GreenCoordinates' kernel on arrays, for their tests. Not API.

#include <span>

namespace spacewarp::detail {

/// The elementary functions of GreenCoordinates' kernel, exposed for their tests (own
/// approximations, no libm): out[i] = ln(num[i] / den[i]) for finite num[i], den[i] > 0 (normal
/// or subnormal), and out[i] = atan2(y[i], x[i]) for finite y[i], x[i] (0 when both are zero).
/// `baseline` runs the portable x86-64 build of the code instead of the one the kernel runs on
/// (detail::simd::activePath()); every path gives the same bits. Throws InvalidInput if the
/// sizes differ.
void greenLogRatio(std::span<const double> num, std::span<const double> den, std::span<double> out,
                   bool baseline = false);
void greenAtan2(std::span<const double> y, std::span<const double> x, std::span<double> out,
                bool baseline = false);

}  // namespace spacewarp::detail
