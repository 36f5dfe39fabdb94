#pragma once
// The one home of the SIMD idiom of the batch kernels (mean-value, Green, RBF, lattice,
// binding): GCC/Clang generic vectors of four doubles, a few libm-free lane functions, and
// SPACEWARP_SIMD_CLONES, which compiles a function for x86-64-v3 (AVX2 + FMA) and for the
// portable baseline and picks one at load time, so the default build needs no -march flag.
// Kernels whose every path must be testable (mean-value, Green) are instead compiled once per
// Path with SPACEWARP_SIMD_TARGET_* (and may use wider vectors there, Lanes<8> on x86-64-v4), and
// the caller picks one by activePath(): target_clones chooses by CPU at load time, and no test
// could then reach the other clones.
//
// Rules the kernels follow, and why the helpers look as they do:
//  - vectors are passed by reference: by value, a 32-byte vector has a different ABI in the two
//    clones (GCC notes that with -Wpsabi, silenced below for every file that includes this);
//  - helpers are always inlined, so that each clone compiles them for its own target;
//  - no libm calls and no branches on lane values: a lane's result is bit-identical whichever
//    lane, group of points or thread computes it.

#include <cstdint>
#include <cstring>
#include <optional>

#if defined(__x86_64__)
#include <emmintrin.h>
#endif

#if defined(__clang__)
#pragma clang diagnostic ignored "-Wpsabi"
#elif defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

#if defined(__x86_64__)
#define SPACEWARP_SIMD_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#define SPACEWARP_SIMD_TARGET_V3 __attribute__((target("arch=x86-64-v3")))
#define SPACEWARP_SIMD_TARGET_V4 __attribute__((target("arch=x86-64-v4")))
#else
#define SPACEWARP_SIMD_CLONES
#define SPACEWARP_SIMD_TARGET_V3
#define SPACEWARP_SIMD_TARGET_V4
#endif

namespace spacewarp::detail::simd {

/// The instruction sets a dispatched kernel is compiled for: the portable x86-64 baseline,
/// x86-64-v3 (AVX2, FMA) and x86-64-v4 (AVX-512 F/BW/CD/DQ/VL). Off x86-64 every path is the
/// portable code.
enum class Path : int { Baseline = 0, V3 = 1, V4 = 2 };
constexpr int kPathCount = 3;

/// "baseline", "x86-64-v3", "x86-64-v4".
const char* pathName(Path path);

/// Whether this CPU runs `path` (off x86-64: Baseline only).
bool pathSupported(Path path);

/// The path dispatched kernels take: the one forcePath() set, else the one the environment
/// variable SPACEWARP_SIMD names (baseline, x86-64-v3 or x86-64-v4; read once), else the best
/// one this CPU supports. Throws InvalidInput naming SPACEWARP_SIMD if it names no path or one
/// this CPU lacks. Files compiled with -ffp-contract=off give the same bits on every path.
Path activePath();

/// Forces `path` for every dispatched kernel of the process (tests and benchmarks), or, with
/// nullopt, returns to the default choice. Throws InvalidInput if the CPU lacks `path`. Not to
/// be called while kernels run on other threads.
void forcePath(std::optional<Path> path);

constexpr int kLanes = 4;  // doubles per vector: one ymm register in the x86-64-v3 clone

/// Vectors of N doubles, their masks and their bits. N = 4 fills a ymm register (x86-64-v3),
/// N = 8 a zmm register (x86-64-v4); the helpers below take any of them.
template <int N>
struct Lanes {
  typedef double D __attribute__((vector_size(N * sizeof(double))));
  typedef std::int64_t I __attribute__((vector_size(N * sizeof(double))));   // masks
  typedef std::uint64_t U __attribute__((vector_size(N * sizeof(double))));  // bits
};
template <class V>
constexpr int kLanesOf = static_cast<int>(sizeof(V) / sizeof(double));
template <class V>
using BitsOf = typename Lanes<kLanesOf<V>>::U;
template <class V>
using MaskOf = typename Lanes<kLanesOf<V>>::I;

using VD = Lanes<kLanes>::D;
using VI = Lanes<kLanes>::I;
using VU = Lanes<kLanes>::U;

// y = 1/√x for x ≥ 0 by Newton's iteration from the bit-level estimate: no libm, no errno, so
// the loop vectorises; accurate to about one ulp, finite (and x y = 0) at x = 0.
template <class V>
[[gnu::always_inline]] inline void rsqrt(const V& x, V& y) {
  using U = BitsOf<V>;
  y = reinterpret_cast<V>(std::uint64_t{0x5FE6EB50C7B537A9} - (reinterpret_cast<U>(x) >> 1));
  const V h = 0.5 * x;
  y = y * (1.5 - h * y * y);
  y = y * (1.5 - h * y * y);
  y = y * (1.5 - h * y * y);
  y = y + y * (0.5 - h * y * y);
}

// y = |x|, by clearing the sign bits.
template <class V>
[[gnu::always_inline]] inline void absLanes(const V& x, V& y) {
  using U = BitsOf<V>;
  y = reinterpret_cast<V>(reinterpret_cast<U>(x) & std::uint64_t{0x7fffffffffffffff});
}

#if defined(__x86_64__)
// The correctly rounded square root (sqrtpd on each pair of lanes: exact like std::sqrt,
// without its errno check, which keeps the loop from vectorising).
template <class V>
[[gnu::always_inline]] inline void sqrtLanes(const V& x, V& y) {
  constexpr int kHalves = kLanesOf<V> / 2;
  __m128d half[kHalves];
  std::memcpy(half, &x, sizeof x);
  for (int i = 0; i < kHalves; ++i) half[i] = _mm_sqrt_pd(half[i]);
  std::memcpy(&y, half, sizeof y);
}

// Whether some lane of a mask is set. Kernels branch on it only to skip work that no lane
// needs: every lane's values are computed by the same instructions whichever way they go.
template <class M>
[[gnu::always_inline]] inline bool anyLane(const M& mask) {
  constexpr int kHalves = kLanesOf<M> / 2;
  __m128d half[kHalves];
  std::memcpy(half, &mask, sizeof mask);
  for (int i = 1; i < kHalves; ++i) half[0] = _mm_or_pd(half[0], half[i]);
  return _mm_movemask_pd(half[0]) != 0;
}
#else
template <class V>
[[gnu::always_inline]] inline void sqrtLanes(const V& x, V& y) {
  for (int l = 0; l < kLanesOf<V>; ++l) y[l] = __builtin_sqrt(x[l]);
}

template <class M>
[[gnu::always_inline]] inline bool anyLane(const M& mask) {
  bool any = false;
  for (int l = 0; l < kLanesOf<M>; ++l) any |= mask[l] != 0;
  return any;
}
#endif

}  // namespace spacewarp::detail::simd
