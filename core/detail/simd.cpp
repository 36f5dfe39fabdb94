#include <spacewarp/core/detail/simd.h>

#include <atomic>
#include <cstdlib>
#include <string>

#include <spacewarp/core/errors.h>

namespace spacewarp::detail::simd {

namespace {

constexpr const char* kNames[kPathCount] = {"baseline", "x86-64-v3", "x86-64-v4"};

// -1: not chosen yet; otherwise the Path. One relaxed load per kernel call (per 4 points).
std::atomic<int> gActive{-1};

Path best() {
  for (int p = kPathCount - 1; p > 0; --p)
    if (pathSupported(static_cast<Path>(p))) return static_cast<Path>(p);
  return Path::Baseline;
}

Path fromEnvironment() {
  const char* text = std::getenv("SPACEWARP_SIMD");
  if (text == nullptr || *text == '\0') return best();
  for (int p = 0; p < kPathCount; ++p) {
    if (std::string(text) != kNames[p]) continue;
    if (!pathSupported(static_cast<Path>(p))) {
      throw InvalidInput(std::string("SPACEWARP_SIMD=") + text + ": this CPU does not support " +
                         kNames[p]);
    }
    return static_cast<Path>(p);
  }
  throw InvalidInput(std::string("SPACEWARP_SIMD=") + text +
                     ": not a SIMD path (baseline, x86-64-v3, x86-64-v4)");
}

}  // namespace

const char* pathName(Path path) { return kNames[static_cast<int>(path)]; }

bool pathSupported(Path path) {
#if defined(__x86_64__)
  switch (path) {
    case Path::Baseline:
      return true;
#if defined(__clang__)
    // Clang 14 knows no level names here: the features that matter to these kernels.
    case Path::V3:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
             __builtin_cpu_supports("bmi2");
    case Path::V4:
      return pathSupported(Path::V3) && __builtin_cpu_supports("avx512f") &&
             __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512cd") &&
             __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512vl");
#else
    case Path::V3:
      return __builtin_cpu_supports("x86-64-v3");
    case Path::V4:
      return __builtin_cpu_supports("x86-64-v4");
#endif
  }
  return false;
#else
  return path == Path::Baseline;
#endif
}

Path activePath() {
  const int active = gActive.load(std::memory_order_relaxed);
  if (active >= 0) return static_cast<Path>(active);
  const Path chosen = fromEnvironment();
  gActive.store(static_cast<int>(chosen), std::memory_order_relaxed);
  return chosen;
}

void forcePath(std::optional<Path> path) {
  if (!path) {
    gActive.store(-1, std::memory_order_relaxed);
    return;
  }
  if (!pathSupported(*path))
    throw InvalidInput(std::string("forcePath: this CPU does not support ") + pathName(*path));
  gActive.store(static_cast<int>(*path), std::memory_order_relaxed);
}

}  // namespace spacewarp::detail::simd
