#pragma once
// Shared internals of the file readers and writers (OBJ, OFF, PLY): strict number parsing,
// shortest round-trip number writing, buffered output and the located IoError messages.
// Not public API.

#include <cstddef>
#include <cstdint>
#include <ostream>
#include <string>
#include <string_view>

namespace spacewarp::detail {

// ---------------------------------------------------------------------------------------------
// Reading

/// What parsing a number token found.
enum class NumberStatus {
  Ok,          ///< A number, correctly rounded.
  NotANumber,  ///< Not one whole number: empty, junk, trailing characters, "+-1", "++1".
  Underflow,   ///< Too small in magnitude: the value is the nearest representable (0 or subnormal).
  OutOfRange,  ///< Too large in magnitude: the value is +-infinity.
};

/// Parses a whole token as a double with correct rounding (std::from_chars, general format, so
/// "inf" and "nan" are numbers). Accepts one leading '+' (before a digit or '.', not "+-1").
NumberStatus parseDouble(std::string_view token, double& value);

/// parseDouble for a float: correctly rounded to single precision.
NumberStatus parseFloat(std::string_view token, float& value);

/// Parses a whole token as a decimal integer with an optional sign ('+' or '-'); false for
/// anything else, including a value outside the range of std::int64_t.
bool parseInteger(std::string_view token, std::int64_t& value);

/// White space of the "C" locale (' ', '\t', '\r', '\n', '\v', '\f'), without a locale lookup.
bool isSpace(char c);

/// Throws IoError "<name>:<line>: <message>" (`name` usually the path, `line` 1-based).
[[noreturn]] void failAt(const std::string& name, std::size_t line, const std::string& message);

/// For a reader's `catch (...)`: rethrows the exception in flight as an IoError naming `name`.
/// An IoError passes unchanged, std::bad_alloc becomes "<name>: out of memory while reading it",
/// any other std::exception "<name>: <what()>"; anything not derived from std::exception passes
/// unchanged.
[[noreturn]] void rethrowAsIoError(const std::string& name);

// ---------------------------------------------------------------------------------------------
// Writing

/// Appends the shortest decimal form that reads back to the identical value (std::to_chars).
void appendNumber(std::string& out, double value);
void appendNumber(std::string& out, float value);

/// Appends an integer in decimal.
void appendInteger(std::string& out, std::int64_t value);
void appendInteger(std::string& out, std::uint64_t value);

/// Hands `buffer` to `out` and empties it once it holds 64 KiB or more, or always if `force`.
/// Stream errors are left in the state of `out`.
void drain(std::string& buffer, std::ostream& out, bool force = false);

}  // namespace spacewarp::detail
