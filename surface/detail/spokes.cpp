#include <spacewarp/surface/detail/spokes.h>

namespace spacewarp::detail {

Spokes makeSpokes(const Eigen::SparseMatrix<double>& laplacian, std::span<const Vec3> rest) {
  Spokes s;
  s.offsets.push_back(0);
  for (Eigen::Index i = 0; i < laplacian.outerSize(); ++i) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(laplacian, i); it; ++it) {
      if (it.row() == i || it.value() == 0.0) continue;
      s.neighbor.push_back(static_cast<std::uint32_t>(it.row()));
      s.weight.push_back(-it.value());
      s.rest.push_back(rest[static_cast<std::size_t>(i)] -
                       rest[static_cast<std::size_t>(it.row())]);
    }
    s.offsets.push_back(s.neighbor.size());
  }
  return s;
}

}  // namespace spacewarp::detail
