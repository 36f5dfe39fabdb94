#include <spacewarp/ffd/lattice_coordinates.h>

#include <algorithm>
#include <string>
#include <vector>

#include <spacewarp/core/archive.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/ffd/lattice_warp.h>

namespace spacewarp {

void LatticeCoordinates::weights(const Vec3& x, std::span<double> row) const {
  checkWeightsArguments(x, row.size());
  std::vector<SparseWeight> sparse(maxNonZeros());
  const std::size_t n = lattice_.sparseWeights(x, sparse);
  std::fill(row.begin(), row.end(), 0.0);
  for (std::size_t e = 0; e < n; ++e) row[sparse[e].column] = sparse[e].weight;
}

std::size_t LatticeCoordinates::sparseWeights(const Vec3& x, std::span<SparseWeight> out) const {
  return lattice_.sparseWeights(x, out);
}

bool LatticeCoordinates::weightGradients(const Vec3& x, std::span<Vec3> out) const {
  if (out.size() != columnCount())
    throw InvalidInput("LatticeCoordinates: the gradient output has " + std::to_string(out.size()) +
                       " entries, " + std::to_string(columnCount()) + " expected");
  std::vector<SparseWeight> sparse(maxNonZeros());
  std::vector<Vec3> gradients(maxNonZeros());
  const std::size_t n = lattice_.sparseWeights(x, sparse, gradients);
  std::fill(out.begin(), out.end(), Vec3(0.0));
  for (std::size_t e = 0; e < n; ++e) out[sparse[e].column] = gradients[e];
  return true;
}

std::shared_ptr<const Warp> LatticeCoordinates::makeWarpFor(std::shared_ptr<const Coordinates>,
                                                            std::span<const Vec3> posed) const {
  return std::make_shared<LatticeWarp>(lattice_, posed);
}

void LatticeCoordinates::save(ArchiveWriter& out) const {
  out.tag("lattice");
  lattice_.save(out);
}

std::shared_ptr<const LatticeCoordinates> LatticeCoordinates::load(ArchiveReader& in) {
  return std::make_shared<const LatticeCoordinates>(Lattice::load(in));
}

}  // namespace spacewarp
