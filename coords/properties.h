#pragma once
// The coordinate property kit: measures the properties that cage coordinates are expected to
// have, for any Coordinates and sample points, and returns numbers a test suite can assert on.

#include <cstdint>
#include <span>
#include <vector>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/coordinates.h>

namespace spacewarp {

/// Options of measureProperties().
struct PropertyOptions {
  /// Random points (uniform barycentric) per cage triangle for the face-interpolation check.
  std::size_t faceSamplesPerTriangle = 4;
  /// Seed of those random points (the report is deterministic for a given seed).
  std::uint64_t seed = 1;
  /// The similarity used for the similarity-reproduction check: rotation angle (radians) about
  /// the axis, uniform scale, and translation in units of the cage diagonal.
  double similarityAngle = 0.7;
  Vec3 similarityAxis{1.0, 2.0, 3.0};
  double similarityScale = 1.3;
  Vec3 similarityTranslation{0.1, -0.2, 0.3};
};

/// What measureProperties() found. Errors are maxima over the samples; lengths are relative to
/// the cage's bounding-box diagonal. Only the first controlPointCount() columns (the vertex
/// weights) count for partition of unity, signs, Lagrange and face interpolation; the face
/// columns of Green coordinates count for linear and similarity reproduction.
struct PropertyReport {
  std::size_t sampleCount = 0;
  double partitionOfUnity = 0.0;  ///< max |Σ_i w_i(x) − 1|
  /// max |Σ_c w_c(x) (C_c(rest) − o) − (x − o)| / diagonal, o the center of the controls'
  /// bounding box (vertex columns are shifted by o, Green's face columns are not): the same as
  /// |Σ_c w_c C_c − x| when the weights sum to 1, and independent of where the world origin is.
  double linearReproduction = 0.0;
  double minWeight = 0.0;            ///< smallest vertex weight at any sample
  double negativeFraction = 0.0;     ///< fraction of (sample, vertex) weights below zero
  double samplesWithNegative = 0.0;  ///< fraction of samples with at least one negative weight
  /// max |w_i(v_j) − δ_ij| over the cage vertices v_j (interpolating coordinates have 0).
  /// NaN when the controls are not the cage's vertices (the check does not apply).
  double lagrange = 0.0;
  /// Interpolation on faces, at random points on the cage's triangles (0 for coordinates that
  /// interpolate on faces). On a triangle face: max |w(x) − barycentric(x)| (the interpolant is
  /// linear). On a polygon face, whose interpolant depends on the method (bilinear for QMVC's
  /// quads, 2D Wachspress or mean value on a planar polygon): the largest of |w_i(x)| for the
  /// vertices i off the face, |Σ_face w_i − 1| and |Σ_face w_i v_i − x| / diagonal, i.e. the
  /// row is supported on the face's vertices and reproduces x. On a non-planar polygon the
  /// points lie on the face's triangles, which are that face only for triangle methods (QMVC's
  /// face is the bilinear patch). NaN when the controls are not the cage's vertices.
  double faceInterpolation = 0.0;
  /// max |x' − S(x)| / diagonal, where the cage is posed by the similarity S (rotation, uniform
  /// scale, translation) and x' is the deformed sample. 0 for coordinates that reproduce
  /// similarities (Green); other coordinates reproduce only affine maps of the whole cage, and a
  /// similarity is affine, so every linearly precise coordinate passes this too.
  double similarityReproduction = 0.0;
};

/// Measures every property of `coordinates` (whose control points must be the vertices of
/// `cage`) at `samples` (n points, world units). Throws InvalidInput if the coordinates'
/// control-point count differs from the cage's vertex count or `samples` is empty.
PropertyReport measureProperties(const Coordinates& coordinates, const Cage& cage,
                                 std::span<const Vec3> samples,
                                 const PropertyOptions& options = {});

/// The properties that do not need the controls to be cage vertices (partition of unity,
/// linear and similarity reproduction, signs), for coordinates with any controls (a lattice,
/// RBF handles): lengths relative to `diagonal` (world units, > 0), the similarity about the
/// center of the controls' bounding box. lagrange and faceInterpolation are NaN. Throws
/// InvalidInput if `samples` is empty or `diagonal` is not positive.
PropertyReport measureProperties(const Coordinates& coordinates, std::span<const Vec3> samples,
                                 double diagonal, const PropertyOptions& options = {});

/// The memory (bytes) measureProperties() allocates for coordinates of `columns` columns and,
/// with a cage, its `cageTriangles` triangles (0 for the overload without one): the weight rows
/// are formed in blocks of about 32 MB (at least 256 rows), so this does not grow with the
/// number of samples. The coordinates' own working memory (per-thread scratch) is not counted.
double measurePropertiesMemory(std::size_t columns, std::size_t cageTriangles,
                               const PropertyOptions& options = {});

/// `count` points drawn uniformly inside `cage` (rejection sampling in its bounding box with the
/// winding number), deterministic for a given seed: the sample set the comparison report uses.
std::vector<Vec3> interiorSamples(const Cage& cage, std::size_t count, std::uint64_t seed = 1);

}  // namespace spacewarp
