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

std::string summaryLine(const std::string& verb, const std::string& what, double seconds,
                        const std::string& output, std::size_t warnings) {
  char time[32];
  std::snprintf(time, sizeof time, "%.3g s", seconds);
  std::string line = verb + " " + what + " in " + time + " -> " + output;
  if (warnings > 0) line += ", " + counted(warnings, "warning");
  return line;
}

}  // namespace spacewarp::cli
