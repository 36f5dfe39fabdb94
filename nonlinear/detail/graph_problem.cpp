#include <spacewarp/nonlinear/detail/graph_problem.h>

#include <algorithm>

namespace spacewarp::detail {

void Problem::evaluate(const std::vector<Mat3>& a, const std::vector<Vec3>& t, double& eRot,
                       double& eReg, double& eCon, double* rhs) const {
  eRot = eReg = eCon = 0.0;
  if (rhs) std::fill(rhs, rhs + unknowns, 0.0);
  addRotation(a, eRot, rhs);
  addRegularization(a, t, eReg, rhs);
  addConstraints(a, t, eCon, rhs);
}

// E_rot: for each free node, (c_p · c_q)² over its column pairs and (1 − c·c)² over its
// columns.
void Problem::addRotation(const std::vector<Mat3>& a, double& eRot, double* rhs) const {
  const double wRot = sRot * sRot;
  constexpr int kPairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  for (std::uint32_t j : freeNodes) {
    const Mat3& m = a[j];
    double* x = rhs ? rhs + var[j] : nullptr;
    for (const auto& pq : kPairs) {  // c_p · c_q: gradient c_q for c_p and c_p for c_q
      const double v = glm::dot(m[pq[0]], m[pq[1]]);
      eRot += v * v;
      if (x) {
        for (int r = 0; r < 3; ++r) {
          x[3 * pq[0] + r] -= wRot * v * m[pq[1]][r];
          x[3 * pq[1] + r] -= wRot * v * m[pq[0]][r];
        }
      }
    }
    for (int c = 0; c < 3; ++c) {  // 1 − c·c: gradient −2 c
      const double v = 1.0 - glm::dot(m[c], m[c]);
      eRot += v * v;
      if (x)
        for (int r = 0; r < 3; ++r) x[3 * c + r] += 2.0 * wRot * v * m[c][r];
    }
  }
}

// E_reg: over the directed edges (j, k), |A_j (g_k − g_j) + g_j + t_j − (g_k + t_k)|².
void Problem::addRegularization(const std::vector<Mat3>& a, const std::vector<Vec3>& t,
                                double& eReg, double* rhs) const {
  const double wReg = sReg * sReg;
  for (const auto& [j, k] : regEdges) {
    // Written to vanish exactly at rest.
    const Vec3 d = nodes[k] - nodes[j];
    const Vec3 e = (a[j] - Mat3(1.0)) * d + t[j] - t[k];
    eReg += glm::dot(e, e);
    if (rhs) {
      double* xj = rhs + var[j];
      double* xk = rhs + var[k];
      for (int r = 0; r < 3; ++r) {
        const double s = wReg * e[r];
        for (int c = 0; c < 3; ++c) xj[3 * c + r] -= s * d[c];
        xj[9 + r] -= s;
        xk[9 + r] += s;
      }
    }
  }
}

// E_con: over the handles, |warp(handle) − target|².
void Problem::addConstraints(const std::vector<Mat3>& a, const std::vector<Vec3>& t, double& eCon,
                             double* rhs) const {
  const double wCon = sCon * sCon;
  const int k = g.k;
  for (std::size_t l = 0; l < handles.size(); ++l) {
    const Vec3& v = handles[l];
    Vec3 d(0.0);
    for (int i = 0; i < k; ++i) {
      const std::uint32_t j = hNodes[l * k + i];
      d += hWeights[l * k + i] * ((a[j] - Mat3(1.0)) * (v - nodes[j]) + t[j]);
    }
    const Vec3 e = v + d - targets[l];
    eCon += glm::dot(e, e);
    if (!rhs) continue;
    for (int i = 0; i < k; ++i) {
      const std::uint32_t j = hNodes[l * k + i];
      if (var[j] < 0) continue;
      double* x = rhs + var[j];
      const double w = wCon * hWeights[l * k + i];
      const Vec3 dv = v - nodes[j];
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) x[3 * c + r] -= w * e[r] * dv[c];
        x[9 + r] -= w * e[r];
      }
    }
  }
}

}  // namespace spacewarp::detail
