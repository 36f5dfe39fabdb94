#pragma once
// One surface edit of a welded soup, whichever the method, and the soup carried along: what the
// command line's `spacewarp edit` and Python's spacewarp.edit() both run, so that they agree bit
// for bit.

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include <spacewarp/core/coordinates.h>
#include <spacewarp/core/geometry.h>
#include <spacewarp/core/progress.h>
#include <spacewarp/surface/arap.h>
#include <spacewarp/surface/cage_arap.h>
#include <spacewarp/surface/handles.h>
#include <spacewarp/surface/laplacian_editing.h>
#include <spacewarp/surface/surface_mesh.h>

namespace spacewarp {

enum class SurfaceEditMethod { Laplacian, BiLaplacian, Arap, CageArap };

struct SurfaceEditOptions {
  SurfaceEditMethod method = SurfaceEditMethod::Arap;
  ArapOptions arap;          ///< for Arap
  CageArapOptions cageArap;  ///< for CageArap
  /// CageArap: the coordinates whose control points are the unknowns (required).
  std::shared_ptr<const Coordinates> coordinates;
};

struct SurfaceEdit {
  std::vector<Vec3> positions;                   ///< every mesh vertex, edited (world units)
  std::vector<std::uint32_t> heldVertices;       ///< mesh vertices no handle reaches (kept at rest)
  std::optional<ArapReport> arapReport;          ///< Arap
  std::optional<CageArapReport> cageArapReport;  ///< CageArap
  std::vector<Vec3> controlPoints;               ///< CageArap: the posed control points
  std::size_t clusterCount = 0;                  ///< CageArap
};

/// Edits `mesh` with `constraints` (mesh vertices and targets) by `options.method`. Throws what
/// the editors throw, InvalidInput if CageArap has no coordinates, SolverError if a vertex ends
/// up not finite.
SurfaceEdit editMesh(const SurfaceMesh& mesh, const VertexConstraints& constraints,
                     const SurfaceEditOptions& options, const ProgressCallback& progress = {});

/// Carries an edit of `mesh` (welded from `soup`) back to the soup: positions from their mesh
/// vertices; per-vertex normals recomputed at the edited positions (area-weighted over the soup's
/// own polygons, so welded copies of a flat-shaded soup stay flat; each on the side of the
/// input's normal); corner normals turned by their polygon's rotation from rest to edited
/// (a normal shared by several corners becomes the normalised sum of its rotations, so smooth
/// shading stays smooth and a flat face's normal turns exactly with it).
void applyEdit(PolygonSoup& soup, const SurfaceMesh& mesh, std::span<const Vec3> edited);

}  // namespace spacewarp
