#pragma once
// A tetrahedral mesh of a cage's interior, made by TetGen (Si, "TetGen, a Delaunay-based quality
// tetrahedral mesh generator", ACM TOMS 2015) as a constrained Delaunay refinement of the cage
// as a piecewise-linear complex. Only built when SPACEWARP_WITH_TETGEN is ON (TetGen is
// AGPL-3.0); the harmonic coordinates (coords/harmonic.h) are its user.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <spacewarp/coords/cage.h>
#include <spacewarp/core/progress.h>

namespace spacewarp {

/// Quality and size of a tetrahedralisation.
struct TetMeshOptions {
  /// Upper bound on every tet's circumradius / shortest edge (TetGen's -q). TetGen's default;
  /// bounds below ~1.1 may not terminate. Must be finite and ≥ 1.
  double radiusEdgeRatio = 2.0;
  /// Upper bound on every tet's volume in world units³ (TetGen's -a, given to it in the cage
  /// frame's units); 0 means none (the mesh is
  /// then only as fine as the quality bound needs). Must be finite and ≥ 0. Refinement under
  /// this bound gives tets whose mean volume is about 0.4 of it.
  double maxTetVolume = 0.0;
};

/// A conforming tetrahedralisation of a cage's interior. Every cage triangle is a union of
/// boundary faces of the mesh; TetGen may add (Steiner) vertices on cage edges and triangles.
/// The mesh is made in the cage's frame (Cage::frame()), so that its geometry has the same
/// relative accuracy wherever the cage is and whatever its size; computations on it (assembly,
/// point location) use localVertices.
struct TetMesh {
  /// The cage's frame, in which localVertices are.
  CageFrame frame;
  /// All mesh vertices in the frame's units, as TetGen made them. The first cage.vertexCount()
  /// are frame.toLocal() of the cage vertices, in the cage's order and bit-identical to it.
  std::vector<Vec3> localVertices;
  /// The same vertices in world units (frame.toWorld(localVertices), except that the first
  /// cage.vertexCount() are the cage vertices, bit-identical).
  std::vector<Vec3> vertices;
  /// Corner indices of every tet, positively oriented (det(p1 − p0, p2 − p0, p3 − p0) > 0 in
  /// localVertices). Some may be flat (isFlatTet, coords/tet_locator.h): TetGen rounds the
  /// Steiner points of a slanted cage face off its plane and fills the round-off gaps; such tets
  /// hold no point (TetLocator) and no stiffness (the harmonic assembly).
  std::vector<std::array<std::uint32_t, 4>> tets;
  /// Per vertex: the cage triangle it lies on (the lowest index when it is on several), or −1
  /// for an interior vertex. Cage vertices lie on their triangles too.
  std::vector<std::int32_t> boundaryTriangle;
};

/// Tetrahedralises the interior of `cage` with TetGen (switches "pzQ" with "q" and "a" from
/// `options`; TetGen prints nothing). Reports the stage "tetrahedralise" to `progress` (start
/// and end only: TetGen offers no finer hook) and throws Cancelled if it asks to stop.
/// Throws InvalidInput for out-of-range options, for a self-intersecting cage (naming two of
/// the intersecting triangles; checked first, since TetGen cannot mesh such input) and for
/// any other input TetGen rejects, with TetGen's reason; SolverError if TetGen fails
/// internally or dies (it runs in a child process, so that a failed assertion of Debian's
/// TetGen, which aborts, names the cage and TetGen's message instead of ending the caller),
/// OutOfMemory (a SolverError) if it runs out of memory.
TetMesh tetrahedraliseCage(const Cage& cage, const TetMeshOptions& options = {},
                           const ProgressCallback& progress = {});

/// The world positions of mesh vertices given in `frame` (the cage's): the cage vertices for
/// the first cage.vertexCount(), bit-identical, frame.toWorld() of the others.
std::vector<Vec3> worldVertices(const Cage& cage, const CageFrame& frame,
                                std::span<const Vec3> localVertices);

}  // namespace spacewarp
