#pragma once
// Typed exceptions. The library never aborts the process: every failure is one of these,
// with a message that names the file, line, element or index at fault.

#include <stdexcept>
#include <string>

namespace spacewarp {

/// Input that violates a documented precondition: NaN coordinates, an empty set, an open cage,
/// a degenerate lattice, a malformed rig.
class InvalidInput : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// A numerical method that could not produce a result: a singular system, a failed factorisation.
class SolverError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A file that could not be read or written, or whose content is malformed.
class IoError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace spacewarp
