#include <spacewarp/core/io/detail/text_format.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
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

std::string quotedToken(std::string_view token) {
  std::string text(1, '\'');
  text += printable(token.substr(0, 64));
  text += token.size() > 64 ? "...'" : "'";
  return text;
}

void failAt(const std::string& name, std::size_t line, const std::string& message) {
  throw IoError(name + ":" + std::to_string(line) + ": " + message);
}

void checkNoNul(std::string_view text, const std::string& name, std::size_t line,
                std::uint64_t offset) {
  const void* nul = std::memchr(text.data(), '\0', text.size());
  if (nul == nullptr) return;
  const auto at = offset + static_cast<std::uint64_t>(static_cast<const char*>(nul) - text.data());
  failAt(name, line,
         "unexpected NUL byte (byte offset " + std::to_string(at) + "): not a text file");
}

TextLines::TextLines(std::istream& in, const std::string& name, bool loneCrEndsLine)
    : in_(in), name_(name), loneCrEndsLine_(loneCrEndsLine), buffer_(std::size_t{1} << 16) {}

bool TextLines::refill() {
  if (eof_) return false;
  bufferOffset_ += end_;
  in_.read(buffer_.data(), static_cast<std::streamsize>(buffer_.size()));
  if (in_.bad()) throw IoError(name_ + ": read error");
  const auto count = static_cast<std::size_t>(in_.gcount());
  if (count < buffer_.size()) eof_ = true;
  pos_ = 0;
  end_ = count;
  // The whole block is checked at once, so that binary input fails at its first block even
  // when its lines are long. The block starts inside the line after lineNumber_ (a "\n" that
  // ends the last line read excepted); the lines up to the NUL are counted for the message.
  const std::string_view block(buffer_.data(), count);
  const std::size_t nul = block.find('\0');
  if (nul != std::string_view::npos) {
    std::size_t line = lineNumber_ + 1;
    for (std::size_t i = (skipLf_ && block[0] == '\n') ? 1 : 0; i < nul; ++i) {
      if (block[i] == '\n' || (loneCrEndsLine_ && block[i] == '\r' && block[i + 1] != '\n')) ++line;
    }
    checkNoNul(block, name_, line, bufferOffset_);
  }
  return count > 0;
}

bool TextLines::next(std::string_view& line) {
  line_.clear();
  bool any = false;
  for (;;) {
    if (pos_ == end_ && !refill()) break;
    if (skipLf_) {
      skipLf_ = false;
      if (buffer_[pos_] == '\n') {
        ++pos_;
        continue;
      }
    }
    any = true;
    const char* begin = buffer_.data() + pos_;
    const std::size_t available = end_ - pos_;
    std::size_t length = 0;
    while (length < available && begin[length] != '\n' &&
           !(loneCrEndsLine_ && begin[length] == '\r'))
      ++length;
    if (line_.size() + length > kMaxTextLine) {
      failAt(name_, lineNumber_ + 1,
             "line too long (more than " + std::to_string(kMaxTextLine) + " bytes)");
    }
    line_.append(begin, length);
    pos_ += length;
    if (pos_ < end_) {
      skipLf_ = begin[length] == '\r';  // "\r\n" is one line end, even across blocks
      ++pos_;
      break;
    }
  }
  if (!any) return false;
  ++lineNumber_;
  line = line_;
  return true;
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

void refuseDirectory(const std::filesystem::path& path) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error))
    throw IoError("cannot open " + path.string() + ": it is a directory");
}

void throwCannotOpen(const std::string& name, int code) {
  throw IoError("cannot open " + name + (code != 0 ? ": " + std::string(std::strerror(code)) : ""));
}

std::ifstream openInputFile(const std::filesystem::path& path) {
  refuseDirectory(path);
  errno = 0;
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    const int code = errno;  // before path.string() may allocate
    throwCannotOpen(path.string(), code);
  }
  return in;
}

}  // namespace spacewarp::detail
