#include <spacewarp/core/io/text_format.h>

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <new>
#include <system_error>
#include <type_traits>

#include <spacewarp/core/errors.h>

namespace spacewarp::detail {
namespace {

/// Removes one leading '+' (std::from_chars takes none); false when no number can follow
/// ("", "+", "+-1", "++1").
bool stripPlus(std::string_view& token) {
  const bool plus = !token.empty() && token.front() == '+';
  if (plus) token.remove_prefix(1);
  return !token.empty() && !(plus && (token.front() == '+' || token.front() == '-'));
}

template <typename T>
NumberStatus parseFloatingPoint(std::string_view token, T& value) {
  if (!stripPlus(token)) return NumberStatus::NotANumber;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value, std::chars_format::general);
  if (ptr != end) return NumberStatus::NotANumber;
  if (ec == std::errc::result_out_of_range) {
    // from_chars leaves `value` alone here; strtod/strtof give +-HUGE_VAL or the underflow.
    const std::string copy(token);
    if constexpr (std::is_same_v<T, float>)
      value = std::strtof(copy.c_str(), nullptr);
    else
      value = std::strtod(copy.c_str(), nullptr);
    return std::isfinite(value) ? NumberStatus::Underflow : NumberStatus::OutOfRange;
  }
  return ec == std::errc() ? NumberStatus::Ok : NumberStatus::NotANumber;
}

template <typename T>
void appendChars(std::string& out, T value) {
  char buffer[32];  // The longest shortest form of a double, "-2.2250738585072014e-308", has 24.
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  out.append(buffer, result.ptr);
}

}  // namespace

NumberStatus parseDouble(std::string_view token, double& value) {
  return parseFloatingPoint(token, value);
}

NumberStatus parseFloat(std::string_view token, float& value) {
  return parseFloatingPoint(token, value);
}

bool parseInteger(std::string_view token, std::int64_t& value) {
  if (!stripPlus(token)) return false;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  return ec == std::errc() && ptr == end;
}

bool isSpace(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f';
}

void failAt(const std::string& name, std::size_t line, const std::string& message) {
  throw IoError(name + ":" + std::to_string(line) + ": " + message);
}

void rethrowAsIoError(const std::string& name) {
  try {
    throw;
  } catch (const IoError&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw IoError(name + ": out of memory while reading it");
  } catch (const std::exception& e) {
    throw IoError(name + ": " + e.what());
  }
}

void appendNumber(std::string& out, double value) { appendChars(out, value); }
void appendNumber(std::string& out, float value) { appendChars(out, value); }
void appendInteger(std::string& out, std::int64_t value) { appendChars(out, value); }
void appendInteger(std::string& out, std::uint64_t value) { appendChars(out, value); }

void drain(std::string& buffer, std::ostream& out, bool force) {
  if (force || buffer.size() >= (1u << 16)) {
    out.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    buffer.clear();
  }
}

}  // namespace spacewarp::detail
