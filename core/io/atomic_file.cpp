#include "core/io/atomic_file.h"

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <system_error>
#include <utility>

#include "core/errors.h"

namespace spacewarp {
namespace {

namespace fs = std::filesystem;

std::string quoted(const fs::path& path) {
  std::string text(1, '\'');
  text += path.string();
  text += '\'';
  return text;
}

/// A hard-to-guess suffix: random bits, a process-wide counter and the time, so that
/// concurrent writers (threads or processes) practically never collide. Collisions that do
/// happen are caught by the exclusive create and retried.
std::string uniqueSuffix() {
  static std::atomic<std::uint64_t> counter{0};
  thread_local std::mt19937_64 rng{[] {
    std::random_device device;
    return (static_cast<std::uint64_t>(device()) << 32) ^ device();
  }()};
  const std::uint64_t bits =
      rng() ^ counter.fetch_add(1, std::memory_order_relaxed) ^
      static_cast<std::uint64_t>(std::chrono::steady_clock::now().time_since_epoch().count());
  char buffer[17];
  std::snprintf(buffer, sizeof buffer, "%016llx", static_cast<unsigned long long>(bits));
  return buffer;
}

/// Creates a new, empty file next to `path` that did not exist before (C11 exclusive mode
/// "x", which also applies the umask) and returns its path.
fs::path createTemporaryNextTo(const fs::path& path) {
  const fs::path directory = path.parent_path();
  std::string stem(1, '.');
  stem += path.filename().string();
  stem += '.';
  for (int attempt = 0; attempt < 100; ++attempt) {
    fs::path candidate = directory / (stem + uniqueSuffix() + ".tmp");
    errno = 0;
    if (std::FILE* file = std::fopen(candidate.c_str(), "wbx")) {
      if (std::fclose(file) != 0) {
        const int error = errno;
        std::error_code ignored;
        fs::remove(candidate, ignored);
        throw IoError("cannot write " + quoted(path) + ": " + std::strerror(error));
      }
      return candidate;
    }
    if (errno != EEXIST) {
      const int error = errno;
      throw IoError("cannot write " + quoted(path) + ": cannot create a temporary file in " +
                    quoted(directory.empty() ? fs::path(".") : directory) + ": " +
                    std::strerror(error));
    }
  }
  throw IoError("cannot write " + quoted(path) + ": no unique temporary file name found");
}

/// Removes the temporary unless it has been renamed into place.
class TemporaryGuard {
 public:
  explicit TemporaryGuard(fs::path path) : path_(std::move(path)) {}
  TemporaryGuard(const TemporaryGuard&) = delete;
  TemporaryGuard& operator=(const TemporaryGuard&) = delete;
  ~TemporaryGuard() {
    if (!released_) {
      std::error_code ignored;
      fs::remove(path_, ignored);
    }
  }
  void release() { released_ = true; }

 private:
  fs::path path_;
  bool released_ = false;
};

}  // namespace

void writeFileAtomically(const std::filesystem::path& path,
                         const std::function<void(std::ostream&)>& write) {
  if (path.filename().empty() || path.filename() == "." || path.filename() == "..")
    throw IoError("cannot write " + quoted(path) + ": not a file name");

  const fs::path temporary = createTemporaryNextTo(path);
  TemporaryGuard guard(temporary);
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out) throw IoError("cannot write " + quoted(path) + ": cannot open the temporary file");
    write(out);  // Exceptions propagate; the guard removes the temporary.
    out.flush();
    if (!out) throw IoError("cannot write " + quoted(path) + ": write failed");
    out.close();
    if (out.fail()) throw IoError("cannot write " + quoted(path) + ": closing the file failed");
  }
  std::error_code error;
  fs::rename(temporary, path, error);
  if (error) throw IoError("cannot write " + quoted(path) + ": " + error.message());
  guard.release();
}

}  // namespace spacewarp
