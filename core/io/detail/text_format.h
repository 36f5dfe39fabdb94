#pragma once
// Shared internals of the file readers and writers (OBJ, OFF, PLY): strict number parsing,
// shortest round-trip number writing, buffered output and the located IoError messages.
// Not public API.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <istream>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

namespace spacewarp::detail {

// ---------------------------------------------------------------------------------------------
// Opening

/// Throws IoError "cannot open <path>: it is a directory" when `path` is one (checked first by
/// the readers: a folder has no extension, and opening one succeeds on Linux).
void refuseDirectory(const std::filesystem::path& path);

/// Throws IoError "cannot open <name>", with strerror(code) when `code` (errno) is not 0.
[[noreturn]] void throwCannotOpen(const std::string& name, int code);

/// Opens `path` for binary reading, refusing a directory; IoError with errno's reason.
std::ifstream openInputFile(const std::filesystem::path& path);

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

/// A token of the file for a message: in single quotes, its first 64 bytes ("..." after
/// them if longer), with control characters and bytes that are not UTF-8 escaped (printable()
/// in core/errors.h), so that a binary or corrupt file's bytes never reach the terminal raw.
std::string quotedToken(std::string_view token);

/// Throws IoError "<name>:<line>: <message>" (`name` usually the path, `line` 1-based).
[[noreturn]] void failAt(const std::string& name, std::size_t line, const std::string& message);

/// The longest line the text readers take (64 MiB): far more than any real OBJ, OFF or PLY line
/// (a polygon of millions of corners), but a bound on what a file that never ends a line (random
/// bytes, an endless stream) can make them hold.
constexpr std::size_t kMaxTextLine = std::size_t{1} << 26;

/// Throws IoError "<name>:<line>: unexpected NUL byte (byte offset <offset>): not a text file" if
/// `text` holds a NUL; `offset` is the input offset of text[0], `line` the line it is on.
/// Binary content (random bytes, /dev/zero, a compressed file) almost always has one.
void checkNoNul(std::string_view text, const std::string& name, std::size_t line,
                std::uint64_t offset);

/// Reads a text input line by line, in blocks, holding one line at a time: a reader that
/// stops at the first bad line reads little more than that line, however long or endless the
/// input (a FIFO, /dev/zero). Throws IoError naming the input and the line at a NUL byte (see
/// checkNoNul) as soon as the block holding it is read, for a line longer than kMaxTextLine as
/// soon as that many bytes are read, and at a read error.
class TextLines {
 public:
  /// `loneCrEndsLine`: whether a "\r" not followed by "\n" ends a line too (as tinyobjloader
  /// reads OBJ); otherwise lines end at "\n" and a "\r" before it stays in the line.
  TextLines(std::istream& in, const std::string& name, bool loneCrEndsLine);

  /// The next line, without its end; false at the end of the input. `line` is valid until the
  /// next call.
  bool next(std::string_view& line);

  /// The number of the line last read (1-based; 0 before the first).
  std::size_t lineNumber() const { return lineNumber_; }

 private:
  bool refill();

  std::istream& in_;
  std::string name_;
  bool loneCrEndsLine_;
  std::vector<char> buffer_;
  std::size_t pos_ = 0;
  std::size_t end_ = 0;
  std::uint64_t bufferOffset_ = 0;  ///< Input offset of buffer_[0].
  bool eof_ = false;
  bool skipLf_ = false;  ///< The last line ended with "\r": a "\n" next belongs to it.
  std::size_t lineNumber_ = 0;
  std::string line_;
};

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
