#include <spacewarp/core/binding.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>

#if defined(__linux__)
#include <sys/mman.h>
#endif

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <spacewarp/core/detail/memory_budget.h>
#include <spacewarp/core/detail/simd.h>
#include <spacewarp/core/errors.h>

namespace spacewarp {

namespace {

// Rows per task. Fixed, so that the work split (and hence every result) is the same for any
// number of threads.
constexpr std::size_t kRowsPerTask = 256;

template <typename Body>
void forRowBlocks(std::size_t n, Body body) {
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(0, n, kRowsPerTask),
      [&](const tbb::blocked_range<std::size_t>& r) { body(r.begin(), r.end()); },
      tbb::simple_partitioner());
}

// out[i] = rest[i] + Σ_c w[i][c] d[c] for the dense rows [begin, end), with the displacements
// in structure-of-arrays form. One 4-lane accumulator per axis (lane k sums the columns
// c ≡ k mod 4), written with GCC vector types because the auto-vectoriser shuffles this loop;
// the order is fixed, so a row's result does not depend on the thread that computes it.
// Deform should be bound by how fast the weights stream in: the x86-64-v3 (AVX2) clone keeps
// the arithmetic below that bound where the portable SSE2 build cannot.
SPACEWARP_SIMD_CLONES void denseRows(const double* weights, std::size_t m, const double* dx,
                                     const double* dy, const double* dz, const Vec3* rest,
                                     Vec3* out, std::size_t begin, std::size_t end) {
  using V4 = detail::simd::VD;
  for (std::size_t i = begin; i < end; ++i) {
    const double* w = weights + i * m;
    V4 ax = {0, 0, 0, 0}, ay = {0, 0, 0, 0}, az = {0, 0, 0, 0};
    std::size_t c = 0;
    for (; c + 4 <= m; c += 4) {
      V4 wc, vx, vy, vz;  // unaligned loads (a helper returning V4 would change the psABI)
      std::memcpy(&wc, w + c, sizeof wc);
      std::memcpy(&vx, dx + c, sizeof vx);
      std::memcpy(&vy, dy + c, sizeof vy);
      std::memcpy(&vz, dz + c, sizeof vz);
      ax += wc * vx;
      ay += wc * vy;
      az += wc * vz;
    }
    for (; c < m; ++c) {
      ax[0] += w[c] * dx[c];
      ay[0] += w[c] * dy[c];
      az[0] += w[c] * dz[c];
    }
    out[i] = rest[i] + Vec3((ax[0] + ax[1]) + (ax[2] + ax[3]), (ay[0] + ay[1]) + (ay[2] + ay[3]),
                            (az[0] + az[1]) + (az[2] + az[3]));
  }
}

// Large weight matrices are written once by many threads; with transparent huge pages in
// "madvise" mode (Debian's default) asking for them removes most of the first-touch page-fault
// cost of binding (about 3.6 ns per point × triangle on one core for Green coordinates).
void adviseHugePages([[maybe_unused]] void* data, [[maybe_unused]] std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr std::uintptr_t kHuge = std::uintptr_t{1} << 21;
  const auto begin = (reinterpret_cast<std::uintptr_t>(data) + kHuge - 1) & ~(kHuge - 1);
  const auto end = (reinterpret_cast<std::uintptr_t>(data) + bytes) & ~(kHuge - 1);
  if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#endif
}

}  // namespace

Binding::Binding(std::shared_ptr<const Coordinates> coordinates, std::span<const Vec3> points,
                 const ProgressCallback& progress)
    : coordinates_(std::move(coordinates)), restPoints_(points.begin(), points.end()) {
  if (!coordinates_) throw InvalidInput("Binding: the coordinates are null");
  for (std::size_t i = 0; i < restPoints_.size(); ++i) {
    if (!isFinite(restPoints_[i]))
      throw InvalidInput("Binding: point " + std::to_string(i) + " is not finite");
  }
  const std::size_t n = restPoints_.size();
  const std::size_t m = coordinates_->columnCount();
  restColumns_.resize(m);
  coordinates_->columnControls(coordinates_->restControlPoints(), restColumns_);

  const std::size_t k = coordinates_->maxNonZeros();
  sparse_ = 4 * k <= m;
  ProgressTracker tracker(progress, "bind", n);
  if (!sparse_) {
    detail::checkMemory(double(n) * double(m) * sizeof(double),
                        "Binding: the dense weights of " + std::to_string(n) + " points by " +
                            std::to_string(m) + " columns");
    dense_.resize(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(m));
    adviseHugePages(dense_.data(), n * m * sizeof(double));
    // Without a display, one batch; with one, blocks big enough to keep every core busy.
    forEachBlock(
        n, progress ? std::size_t{1} << 14 : 0, tracker, [&](std::size_t begin, std::size_t count) {
          coordinates_->weightsBatch(restPoints_, begin, begin + count,
                                     std::span<double>(dense_.data() + begin * m, count * m));
        });
    return;
  }
  // Sparse: every row gets k slots, filled in parallel, then compacted into CSR.
  std::vector<SparseWeight> slots(n * k);
  std::vector<std::size_t> counts(n);
  forRowBlocks(n, [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i)
      counts[i] = coordinates_->sparseWeights(restPoints_[i], std::span(slots).subspan(i * k, k));
    tracker.advance(end - begin);
  });
  tracker.finish();
  std::vector<Eigen::Triplet<double, std::int64_t>> triplets;
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < counts[i]; ++j) {
      const SparseWeight& s = slots[i * k + j];
      triplets.emplace_back(static_cast<std::int64_t>(i), s.column, s.weight);
    }
  }
  sparseMatrix_.resize(static_cast<std::int64_t>(n), static_cast<std::int64_t>(m));
  sparseMatrix_.setFromTriplets(triplets.begin(), triplets.end());
  sparseMatrix_.makeCompressed();
}

void Binding::deform(std::span<const Vec3> posed, std::span<Vec3> out) const {
  const std::size_t n = pointCount();
  const std::size_t m = columnCount();
  if (out.size() != n) {
    throw InvalidInput("Binding::deform: the output has " + std::to_string(out.size()) +
                       " entries for " + std::to_string(n) + " bound points");
  }
  std::vector<Vec3> columns(m);
  coordinates_->columnControls(posed, columns);
  std::vector<double> dx(m), dy(m), dz(m);
  for (std::size_t c = 0; c < m; ++c) {
    const Vec3 d = columns[c] - restColumns_[c];
    dx[c] = d.x;
    dy[c] = d.y;
    dz[c] = d.z;
  }
  if (!sparse_) {
    forRowBlocks(n, [&](std::size_t begin, std::size_t end) {
      denseRows(dense_.data(), m, dx.data(), dy.data(), dz.data(), restPoints_.data(), out.data(),
                begin, end);
    });
    return;
  }
  const std::int64_t* outer = sparseMatrix_.outerIndexPtr();
  const std::int64_t* inner = sparseMatrix_.innerIndexPtr();
  const double* values = sparseMatrix_.valuePtr();
  forRowBlocks(n, [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      Vec3 sum(0.0);
      for (std::int64_t e = outer[i]; e < outer[i + 1]; ++e) {
        const auto c = static_cast<std::size_t>(inner[e]);
        sum += values[e] * Vec3(dx[c], dy[c], dz[c]);
      }
      out[i] = restPoints_[i] + sum;
    }
  });
}

std::vector<Vec3> Binding::deform(std::span<const Vec3> posed) const {
  std::vector<Vec3> out(pointCount());
  deform(posed, out);
  return out;
}

}  // namespace spacewarp
