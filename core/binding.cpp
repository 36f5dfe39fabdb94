#include "core/binding.h"

#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"

namespace spacewarp {

namespace {

// Rows per task. Fixed, so that the work split (and hence every result) is the same for any
// number of threads.
constexpr std::size_t kRowsPerTask = 256;

template <typename Body>
void forRowBlocks(std::size_t n, Body body) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, kRowsPerTask),
                    [&](const tbb::blocked_range<std::size_t>& r) { body(r.begin(), r.end()); },
                    tbb::simple_partitioner());
}

// Σ_c w[c] d[c] for one dense row, with the displacements in structure-of-arrays form. Four
// independent accumulators per axis hide the add latency; the order is fixed, so the result
// is the same on every thread.
inline Vec3 denseRowTimes(const double* w, const double* dx, const double* dy, const double* dz,
                          std::size_t m) {
  double ax[4] = {0, 0, 0, 0}, ay[4] = {0, 0, 0, 0}, az[4] = {0, 0, 0, 0};
  std::size_t c = 0;
  for (; c + 4 <= m; c += 4) {
    for (int k = 0; k < 4; ++k) {
      ax[k] += w[c + k] * dx[c + k];
      ay[k] += w[c + k] * dy[c + k];
      az[k] += w[c + k] * dz[c + k];
    }
  }
  for (; c < m; ++c) {
    ax[0] += w[c] * dx[c];
    ay[0] += w[c] * dy[c];
    az[0] += w[c] * dz[c];
  }
  return {(ax[0] + ax[1]) + (ax[2] + ax[3]), (ay[0] + ay[1]) + (ay[2] + ay[3]),
          (az[0] + az[1]) + (az[2] + az[3])};
}

}  // namespace

Binding::Binding(std::shared_ptr<const Coordinates> coordinates, std::span<const Vec3> points)
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
  if (!sparse_) {
    dense_.resize(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(m));
    coordinates_->weightsBatch(restPoints_, std::span<double>(dense_.data(), n * m));
    return;
  }
  // Sparse: every row gets k slots, filled in parallel, then compacted into CSR.
  std::vector<SparseWeight> slots(n * k);
  std::vector<std::size_t> counts(n);
  forRowBlocks(n, [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i)
      counts[i] = coordinates_->sparseWeights(restPoints_[i], std::span(slots).subspan(i * k, k));
  });
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
      for (std::size_t i = begin; i < end; ++i)
        out[i] = restPoints_[i] + denseRowTimes(dense_.data() + i * m, dx.data(), dy.data(),
                                                dz.data(), m);
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
