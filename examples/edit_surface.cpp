// Drags the top of a model with as-rigid-as-possible surface editing, its bottom pinned:
//
//   edit_surface INPUT OUTPUT [LIFT]
//
// The vertices within 10% of the model's height from its bottom stay put; those within 10% of
// its top turn by 30° about the vertical axis and rise by LIFT (default 0.2) of the height.
// Every file is OBJ, OFF or PLY by its extension; the output keeps the input's polygons.
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/surface/arap.h>
#include <spacewarp/surface/edit_mesh.h>
#include <spacewarp/surface/handles.h>
#include <spacewarp/surface/surface_mesh.h>

int main(int argc, char** argv) {
  if (argc != 3 && argc != 4) {
    std::fprintf(stderr, "usage: %s INPUT OUTPUT [LIFT]\n", argv[0]);
    return 2;
  }
  try {
    using namespace spacewarp;
    PolygonSoup soup = readSoup(argv[1]);
    const SurfaceMesh mesh = weldSoup(soup);  // one vertex per place: the soup's copies joined
    const BoundingBox box = boundingBox(mesh.positions);
    const double height = box.extent().y;
    const double lift = argc == 4 ? std::atof(argv[3]) : 0.2;

    // Two handle regions, each moved by an affine map (the identity pins).
    std::vector<HandleRegion> regions(2);
    regions[0].matrix = Mat4(1.0);
    const Vec3 axis = 0.5 * (box.min + box.max);
    regions[1].matrix = glm::translate(Mat4(1.0), Vec3(0.0, lift * height, 0.0)) *
                        glm::translate(Mat4(1.0), axis) *
                        glm::rotate(Mat4(1.0), glm::radians(30.0), Vec3(0.0, 1.0, 0.0)) *
                        glm::translate(Mat4(1.0), -axis);
    for (std::uint32_t v = 0; v < mesh.vertexCount(); ++v) {
      if (mesh.positions[v].y <= box.min.y + 0.1 * height) regions[0].vertices.push_back(v);
      if (mesh.positions[v].y >= box.max.y - 0.1 * height) regions[1].vertices.push_back(v);
    }
    const VertexConstraints handles = resolveHandles(regions, mesh.positions);

    // Factorise once; each solve (a new drag) reuses the factor.
    ArapEditor editor(mesh.positions, mesh.triangles, handles.vertices);
    const ArapResult result = editor.solve(handles.targets);
    std::printf("ARAP: %d iterations, energy %.3g -> %.3g%s\n", result.report.iterations,
                result.report.energies.front(), result.report.energies.back(),
                result.report.converged ? "" : " (not converged)");

    // Back to the soup's own vertices, its normals recomputed (per vertex) or turned (per corner).
    applyEdit(soup, mesh, result.positions);
    writeSoup(soup, argv[2]);  // atomic: a failure leaves no partial file
    return 0;
  } catch (const spacewarp::IoError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 3;
  } catch (const spacewarp::InvalidInput& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 3;
  } catch (const spacewarp::SolverError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 4;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
