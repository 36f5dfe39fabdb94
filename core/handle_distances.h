#pragma once
// HandleDistances: the distances from each of n handles to a point x, and their gradients: the
// metric a handle-weighted warp (MlsWarp) weighs its handles with. Euclidean distance is the
// default of those warps; an implementation gives another metric, such as the distance measured
// inside a model (volume/inside_distance.h), without the warp knowing how it is computed.

#include <cstddef>
#include <span>

#include <spacewarp/core/math.h>

namespace spacewarp {

class ArchiveReader;
class ArchiveWriter;

/// Distances d_i(x) from n fixed handles p_i to any point x. Immutable once built; every method
/// is const and thread-safe, and deterministic (the same x gives bit-identical results).
class HandleDistances {
 public:
  virtual ~HandleDistances() = default;

  /// The handles p_i the distances are measured from: n points, world units.
  virtual std::span<const Vec3> handles() const = 0;

  /// d_i(x) for every handle into `distances` (n entries): world units, >= 0, and exactly 0 at
  /// x = p_i. Throws InvalidInput when `distances` does not have n entries.
  virtual void distances(const Vec3& x, std::span<double> distances) const = 0;

  /// d_i(x) as distances() gives them (bit-identical), and their gradients ∇d_i(x) into
  /// `gradients` (n entries, unit-free; any value at x = p_i, where d_i is not differentiable).
  virtual void distancesAndGradients(const Vec3& x, std::span<double> distances,
                                     std::span<Vec3> gradients) const = 0;

  /// Writes these distances to an archive (core/archive.h): their tag, then what rebuilds them
  /// (solved state included). The default throws InvalidInput naming the type.
  virtual void save(ArchiveWriter& out) const;
};

}  // namespace spacewarp
