#include "apps/cli_context.h"

#include <unistd.h>

#include <cstdio>

namespace spacewarp::cli {

ProgressCallback CliContext::progress() const {
  if (quiet || !::isatty(STDERR_FILENO)) return {};
  return [](std::string_view stage, double fraction) {
    std::fprintf(stderr, "\r%-20.*s %3d%%", static_cast<int>(stage.size()), stage.data(),
                 static_cast<int>(fraction * 100.0 + 0.5));
    if (fraction >= 1.0) std::fputc('\n', stderr);
    std::fflush(stderr);
    return true;
  };
}

std::string printable(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", byte);
      out += escaped;
    } else {
      out += c;
    }
  }
  return out;
}

std::string prefixed(const std::string& name, const std::string& what) {
  return what.rfind(name, 0) == 0 ? what : name + ": " + what;
}

void CliContext::say(const std::string& line) const {
  if (!quiet) std::printf("%s\n", line.c_str());
}

void CliContext::warn(const std::string& line) const {
  ++warnings_;
  std::fflush(stdout);  // keep the order of stdout and stderr lines on a terminal
  std::fprintf(stderr, "spacewarp: warning: %s\n", line.c_str());
}

std::string groupDigits(std::size_t n) {
  const std::string digits = std::to_string(n);
  std::string grouped;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) grouped += ',';
    grouped += digits[i];
  }
  return grouped;
}

std::string counted(std::size_t n, const std::string& noun) {
  return groupDigits(n) + " " + noun + (n == 1 ? "" : "s");
}

}  // namespace spacewarp::cli
