#include <spacewarp/core/detail/batch.h>

#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <spacewarp/core/errors.h>

namespace spacewarp::detail {

UnmappedPoints forEachRange(std::size_t n, std::size_t grain,
                            const std::function<UnmappedPoints(std::size_t, std::size_t)>& kernel) {
  if (n == 0) return {};
  grain = std::max<std::size_t>(grain, 1);
  const std::size_t ranges = (n - 1) / grain + 1;
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, ranges, 1), UnmappedPoints{},
      [&](const tbb::blocked_range<std::size_t>& r, UnmappedPoints unmapped) {
        for (std::size_t range = r.begin(); range != r.end(); ++range)
          unmapped.merge(kernel(range * grain, std::min(n, (range + 1) * grain)));
        return unmapped;
      },
      [](UnmappedPoints a, const UnmappedPoints& b) {
        a.merge(b);
        return a;
      });
}

void requireSameSize(const char* who, std::size_t inSize, std::size_t outSize) {
  if (inSize != outSize) {
    throw InvalidInput(std::string(who) + ": input has " + std::to_string(inSize) +
                       " points but output has " + std::to_string(outSize));
  }
}

}  // namespace spacewarp::detail
