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

}  // namespace spacewarp::cli
