#pragma once
// Typed exceptions. The library never aborts the process: every failure is one of these,
// with a message that names the file, line, element or index at fault.

#include <stdexcept>
#include <string>
#include <string_view>

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

/// `text` with control characters (a NUL, a newline in a JSON key or a file name, U+0080 to
/// U+009F) written as \uXXXX, so that a message stays one whole line, and bytes that are not
/// part of well-formed UTF-8 (a binary file's content, Latin-1 text) as \xXX, so that it stays
/// readable text. Well-formed UTF-8 (accented file names) is kept as it is.
std::string printable(std::string_view text);

/// `what` with "<name>: " in front, unless it already starts with `name`.
std::string prefixed(const std::string& name, const std::string& what);

/// Runs `work` and rethrows the typed errors it throws (InvalidInput, SolverError, IoError) with
/// `name` (usually a file) in front of their message, so that errors from the library, which does
/// not know where its input came from, name the file at fault.
template <typename Work>
decltype(auto) namingFile(const std::string& name, Work&& work) {
  try {
    return work();
  } catch (const InvalidInput& e) {
    throw InvalidInput(prefixed(name, e.what()));
  } catch (const SolverError& e) {
    throw SolverError(prefixed(name, e.what()));
  } catch (const IoError& e) {
    throw IoError(prefixed(name, e.what()));
  }
}

}  // namespace spacewarp
