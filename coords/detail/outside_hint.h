#pragma once
// The remedy that every "points are outside the cage" error of a method with an outside policy
// (harmonic, Wachspress, discrete harmonic) ends with, naming the policy in each front end.

namespace spacewarp::detail {

/// Appended to the error: the same policy as spelled by the CLI, rigs, Python and C++.
inline constexpr const char* kNearestHint =
    "the outside policy \"nearest\" gives them the coordinates of the nearest surface point "
    "(--outside nearest in the CLI, \"outside\": \"nearest\" in a rig, outside=\"nearest\" in "
    "Python, the options' outside = NearestPoint in C++)";

}  // namespace spacewarp::detail
