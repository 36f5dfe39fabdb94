#pragma once
// The one parallel loop of the batch paths (Warp::applyBatch, Coordinates::weightsBatch).

#include <cstddef>
#include <functional>

#include <spacewarp/core/warp.h>

namespace spacewarp::detail {

/// Runs kernel(begin, end) over [0, n) in ranges of `grain` points (the last may be shorter),
/// in parallel (TBB), and merges what the ranges could not map. The ranges depend only on n and
/// grain, never on the number of threads.
UnmappedPoints forEachRange(std::size_t n, std::size_t grain,
                            const std::function<UnmappedPoints(std::size_t, std::size_t)>& kernel);

/// Throws InvalidInput unless in.size() == outSize; `who` names the caller.
void requireSameSize(const char* who, std::size_t inSize, std::size_t outSize);

}  // namespace spacewarp::detail
