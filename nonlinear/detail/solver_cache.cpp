#include <spacewarp/nonlinear/detail/solver_cache.h>

#include <algorithm>
#include <cstring>
#include <tuple>
#include <utility>

namespace spacewarp::detail {

namespace {

// The sparse Cholesky of the normal equations. Ordering: AMD alone. CHOLMOD's default would
// also try METIS on a graph this filled; on the 1,000-node benchmark METIS saves ~10 % of the
// factorisation's flops (2.9 vs 3.2 GFlop) but its analysis takes ~90 ms against AMD's ~23 ms.
// The wrapper runs the BLAS single-threaded: on this machine a single BLAS thread is as fast
// as two for the graph's supernodes (measured: 189 vs 197 ms), so determinism costs nothing.
SparseCholeskyOptions choleskyOptions() {
  return {"DeformationGraph::solve", "use fewer graph nodes", CholeskyOrdering::Amd};
}

// Coupled pairs of free nodes (j < k), sorted: 1 = regulariser edge, 2 = a common handle.
std::vector<std::tuple<std::uint32_t, std::uint32_t, int>> couplings(const Problem& p) {
  std::vector<std::tuple<std::uint32_t, std::uint32_t, int>> rel;
  for (const auto& [i, j] : p.g.edges)
    if (p.var[i] >= 0 && p.var[j] >= 0) rel.emplace_back(i, j, 1);
  const int k = p.g.k;
  for (std::size_t l = 0; l < p.handles.size(); ++l) {
    for (int a = 0; a < k; ++a) {
      for (int b = a + 1; b < k; ++b) {
        const std::uint32_t x = p.hNodes[l * k + a], y = p.hNodes[l * k + b];
        if (p.var[x] >= 0 && p.var[y] >= 0 && x != y)
          rel.emplace_back(std::min(x, y), std::max(x, y), 2);
      }
    }
  }
  std::sort(rel.begin(), rel.end());
  return rel;
}

}  // namespace

SolverCache::SolverCache() : cholesky(choleskyOptions()) {}

bool SolverCache::matches(const Problem& p) const {
  return valid && var == p.var && hNodes == p.hNodes && hWeights == p.hWeights &&
         handles == p.handles && sReg == p.sReg && sCon == p.sCon;
}

void SolverCache::build(const Problem& p) {
  valid = false;
  factorValid = false;
  buildPattern(p);
  indexBlocks(p);
  buildConstant(p);
  cholesky.analyzePattern(lower);

  var = p.var;
  hNodes = p.hNodes;
  hWeights = p.hWeights;
  handles = p.handles;
  sReg = p.sReg;
  sCon = p.sCon;
  valid = true;
}

// Columns node by node. Column o of a node (coordinate r = o % 3; o >= 9 is t[r]) meets, in a
// coupled node's block, rows {r, 3+r, 6+r, 9+r} (a common handle, or a regulariser edge seen
// from t) or only 9+r (a regulariser edge seen from A): the regulariser and the constraints
// never mix coordinates, only the rotation term does, within a node.
void SolverCache::buildPattern(const Problem& p) {
  const std::vector<std::tuple<std::uint32_t, std::uint32_t, int>> rel = couplings(p);
  const int n = p.unknowns;
  std::vector<int> outer(std::size_t(n) + 1, 0);
  std::vector<int> inner;
  inner.reserve(std::size_t(n) * 48);
  std::size_t relBegin = 0;
  for (std::uint32_t j : p.freeNodes) {
    while (relBegin < rel.size() && std::get<0>(rel[relBegin]) < j) ++relBegin;
    std::size_t relEnd = relBegin;
    while (relEnd < rel.size() && std::get<0>(rel[relEnd]) == j) ++relEnd;
    const int vj = p.var[j];
    for (int o = 0; o < 12; ++o) {
      const int r = o % 3;
      for (int o2 = o; o2 < 12; ++o2) inner.push_back(vj + o2);
      for (std::size_t e = relBegin; e < relEnd;) {
        const std::uint32_t node = std::get<1>(rel[e]);
        int flags = 0;
        for (; e < relEnd && std::get<1>(rel[e]) == node; ++e) flags |= std::get<2>(rel[e]);
        const int vk = p.var[node];
        if ((flags & 2) || o >= 9) {
          for (int c = 0; c < 4; ++c) inner.push_back(vk + 3 * c + r);
        } else {
          inner.push_back(vk + 9 + r);
        }
      }
      outer[std::size_t(vj + o) + 1] = int(inner.size());
    }
    relBegin = relEnd;
  }
  lower = Eigen::SparseMatrix<double>(n, n);
  lower.resizeNonZeros(Eigen::Index(inner.size()));
  std::copy(outer.begin(), outer.end(), lower.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), lower.innerIndexPtr());
  std::fill(lower.valuePtr(), lower.valuePtr() + inner.size(), 0.0);
}

// Each free node's diagonal block leads its 12 columns (see buildPattern).
void SolverCache::indexBlocks(const Problem& p) {
  const int* outer = lower.outerIndexPtr();
  blockSlots.resize(p.freeNodes.size() * kBlockSlots);
  diagonal.resize(std::size_t(p.unknowns));
  for (std::size_t f = 0; f < p.freeNodes.size(); ++f) {
    const int vj = p.var[p.freeNodes[f]];
    int* s = blockSlots.data() + f * kBlockSlots;
    for (int o = 0; o < 12; ++o) {
      diagonal[std::size_t(vj + o)] = outer[vj + o];
      for (int o2 = o; o2 < 12; ++o2) *s++ = outer[vj + o] + (o2 - o);
    }
  }
}

// The constant part, JᵀJ of the regulariser and constraint rows, one row at a time; also
// written into `lower`.
void SolverCache::buildConstant(const Problem& p) {
  const int* outer = lower.outerIndexPtr();
  const int* inner = lower.innerIndexPtr();
  constant.assign(std::size_t(lower.nonZeros()), 0.0);
  const auto slotOf = [&](int row, int col) {
    if (row < col) std::swap(row, col);
    if (row / 12 == col / 12) return outer[col] + (row - col);
    const int* b = inner + outer[col];
    const int* e = inner + outer[col + 1];
    return int(std::lower_bound(b, e, row) - inner);
  };
  const auto addRow = [&](const int* idx, const double* u, int count) {
    for (int a = 0; a < count; ++a)
      for (int b = 0; b <= a; ++b) constant[std::size_t(slotOf(idx[a], idx[b]))] += u[a] * u[b];
  };
  for (const auto& [j, kk] : p.regEdges) {
    const Vec3 d = p.nodes[kk] - p.nodes[j];
    const int vj = p.var[j], vk = p.var[kk];
    for (int r = 0; r < 3; ++r) {
      const int idx[5] = {vj + r, vj + 3 + r, vj + 6 + r, vj + 9 + r, vk + 9 + r};
      const double u[5] = {p.sReg * d[0], p.sReg * d[1], p.sReg * d[2], p.sReg, -p.sReg};
      addRow(idx, u, 5);
    }
  }
  const int k = p.g.k;
  std::vector<int> idx;
  std::vector<double> u;
  for (std::size_t l = 0; l < p.handles.size(); ++l) {
    for (int r = 0; r < 3; ++r) {
      idx.clear();
      u.clear();
      for (int i = 0; i < k; ++i) {
        const std::uint32_t j = p.hNodes[l * k + i];
        if (p.var[j] < 0) continue;
        const double w = p.sCon * p.hWeights[l * k + i];
        const Vec3 dv = p.handles[l] - p.nodes[j];
        for (int c = 0; c < 3; ++c) {
          idx.push_back(p.var[j] + 3 * c + r);
          u.push_back(w * dv[c]);
        }
        idx.push_back(p.var[j] + 9 + r);
        u.push_back(w);
      }
      addRow(idx.data(), u.data(), int(idx.size()));
    }
  }
  std::copy(constant.begin(), constant.end(), lower.valuePtr());
}

void SolverCache::assemble(const Problem& p, const std::vector<Mat3>& a, Eigen::VectorXd& diag) {
  double* value = lower.valuePtr();
  const double wRot = p.sRot * p.sRot;
  constexpr int kPairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  for (std::size_t f = 0; f < p.freeNodes.size(); ++f) {
    const Mat3& m = a[p.freeNodes[f]];
    // Rows of the rotation Jacobian (9 entries over A) and their Gram matrix.
    double rows[6][9] = {};
    for (int q = 0; q < 3; ++q) {
      for (int r = 0; r < 3; ++r) {
        rows[q][3 * kPairs[q][0] + r] = m[kPairs[q][1]][r];
        rows[q][3 * kPairs[q][1] + r] = m[kPairs[q][0]][r];
        rows[3 + q][3 * q + r] = -2.0 * m[q][r];
      }
    }
    const int* s = blockSlots.data() + f * kBlockSlots;
    for (int o = 0; o < 12; ++o) {
      for (int o2 = o; o2 < 12; ++o2, ++s) {
        double v = constant[std::size_t(*s)];
        if (o2 < 9) {
          double rot = 0.0;
          for (int q = 0; q < 6; ++q) rot += rows[q][o] * rows[q][o2];
          v += wRot * rot;
        }
        value[*s] = v;
      }
    }
  }
  diag.resize(p.unknowns);
  for (int i = 0; i < p.unknowns; ++i) diag[i] = value[diagonal[std::size_t(i)]];
}

void SolverCache::damp(const Eigen::VectorXd& diag, double shift) {
  double* value = lower.valuePtr();
  for (Eigen::Index i = 0; i < diag.size(); ++i) value[diagonal[std::size_t(i)]] = diag[i] + shift;
}

bool SolverCache::factorIsCurrent() const {
  if (!factorValid) return false;
  const double* value = lower.valuePtr();
  for (std::size_t i = 0; i < blockSlots.size(); ++i) {
    if (std::memcmp(&value[blockSlots[i]], &factoredBlocks[i], sizeof(double)) != 0) return false;
  }
  return true;
}

bool SolverCache::factorize() {
  factorValid = false;
  factorValid = cholesky.factorize(lower);
  if (factorValid) {
    const double* value = lower.valuePtr();
    factoredBlocks.resize(blockSlots.size());
    for (std::size_t i = 0; i < blockSlots.size(); ++i) factoredBlocks[i] = value[blockSlots[i]];
  }
  return factorValid;
}

}  // namespace spacewarp::detail
