#pragma once
// The one home of the SIMD idiom of the batch kernels (mean-value, Green, RBF, lattice,
// binding): GCC/Clang generic vectors of four doubles, a few libm-free lane functions, and
// SPACEWARP_SIMD_CLONES, which compiles a function for x86-64-v3 (AVX2 + FMA) and for the
// portable baseline and picks one at load time, so the default build needs no -march flag.
//
// Rules the kernels follow, and why the helpers look as they do:
//  - vectors are passed by reference: by value, a 32-byte vector has a different ABI in the two
//    clones (GCC notes that with -Wpsabi, silenced below for every file that includes this);
//  - helpers are always inlined, so that each clone compiles them for its own target;
//  - no libm calls and no branches on lane values: a lane's result is bit-identical whichever
//    lane, group of points or thread computes it.

#include <cstdint>
#include <cstring>

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
#else
#define SPACEWARP_SIMD_CLONES
#endif

namespace spacewarp::detail::simd {

constexpr int kLanes = 4;  // doubles per vector: one ymm register in the x86-64-v3 clone

typedef double VD __attribute__((vector_size(kLanes * sizeof(double))));
typedef std::int64_t VI __attribute__((vector_size(kLanes * sizeof(double))));   // masks
typedef std::uint64_t VU __attribute__((vector_size(kLanes * sizeof(double))));  // bits

// y = 1/√x for x ≥ 0 by Newton's iteration from the bit-level estimate: no libm, no errno, so
// the loop vectorises; accurate to about one ulp, finite (and x y = 0) at x = 0.
[[gnu::always_inline]] inline void rsqrt(const VD& x, VD& y) {
  y = reinterpret_cast<VD>(std::uint64_t{0x5FE6EB50C7B537A9} - (reinterpret_cast<VU>(x) >> 1));
  const VD h = 0.5 * x;
  y = y * (1.5 - h * y * y);
  y = y * (1.5 - h * y * y);
  y = y * (1.5 - h * y * y);
  y = y + y * (0.5 - h * y * y);
}

// y = |x|, by clearing the sign bits.
[[gnu::always_inline]] inline void absLanes(const VD& x, VD& y) {
  y = reinterpret_cast<VD>(reinterpret_cast<VU>(x) & std::uint64_t{0x7fffffffffffffff});
}

#if defined(__x86_64__)
// The correctly rounded square root (sqrtpd on both halves: exact like std::sqrt, without its
// errno check, which keeps the loop from vectorising).
[[gnu::always_inline]] inline void sqrtLanes(const VD& x, VD& y) {
  __m128d half[2];
  std::memcpy(half, &x, sizeof x);
  half[0] = _mm_sqrt_pd(half[0]);
  half[1] = _mm_sqrt_pd(half[1]);
  std::memcpy(&y, half, sizeof y);
}

// Whether some lane of a mask is set. Kernels branch on it only to skip work that no lane
// needs: every lane's values are computed by the same instructions whichever way they go.
[[gnu::always_inline]] inline bool anyLane(const VI& mask) {
  __m128d half[2];
  std::memcpy(half, &mask, sizeof mask);
  return _mm_movemask_pd(_mm_or_pd(half[0], half[1])) != 0;
}
#else
[[gnu::always_inline]] inline void sqrtLanes(const VD& x, VD& y) {
  for (int l = 0; l < kLanes; ++l) y[l] = __builtin_sqrt(x[l]);
}

[[gnu::always_inline]] inline bool anyLane(const VI& mask) {
  bool any = false;
  for (int l = 0; l < kLanes; ++l) any |= mask[l] != 0;
  return any;
}
#endif

}  // namespace spacewarp::detail::simd
