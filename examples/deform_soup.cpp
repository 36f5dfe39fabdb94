// Deforms a polygon soup (positions and normals) with mean-value cage coordinates:
//
//   deform_soup REST_CAGE POSED_CAGE INPUT OUTPUT
//
// Every file is OBJ, OFF or PLY by its extension. The cage is a closed triangle or polygon
// mesh around INPUT; POSED_CAGE has the same vertices in the same order, moved. Exit codes
// follow the spacewarp tool: 0 success, 3 bad input or file, 4 numerical failure, 1 other.
#include <cstdio>
#include <exception>
#include <memory>
#include <vector>

#include <spacewarp/coords/cage.h>
#include <spacewarp/coords/mean_value.h>
#include <spacewarp/core/coordinate_warp.h>
#include <spacewarp/core/deform.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>

int main(int argc, char** argv) {
  if (argc != 5) {
    std::fprintf(stderr, "usage: %s REST_CAGE POSED_CAGE INPUT OUTPUT\n", argv[0]);
    return 2;
  }
  try {
    // The rest cage is validated (closed, manifold, oriented); the posed one must match it.
    auto cage = std::make_shared<const spacewarp::Cage>(spacewarp::Cage::fromFile(argv[1]));
    const std::vector<spacewarp::Vec3> posed = cage->posedVerticesFromFile(argv[2]);

    // The coordinates of the rest cage and their Warp for this pose: x' = Σ w_i(x) c'_i.
    auto mvc = std::make_shared<const spacewarp::MeanValueCoordinates>(cage);
    const spacewarp::CoordinateWarp warp(mvc, posed);

    spacewarp::PolygonSoup soup = spacewarp::readSoup(argv[3]);
    spacewarp::deform(warp, soup);        // positions through the warp, normals through J^-T
    spacewarp::writeSoup(soup, argv[4]);  // atomic: a failure leaves no partial file
    std::printf("deformed %zu vertices -> %s\n", soup.positions.size(), argv[4]);
    return 0;
  } catch (const spacewarp::IoError& e) {  // unreadable or malformed file, failed write
    std::fprintf(stderr, "error: %s\n", e.what());
    return 3;
  } catch (const spacewarp::InvalidInput& e) {  // open cage, NaN coordinates, wrong pose
    std::fprintf(stderr, "error: %s\n", e.what());
    return 3;
  } catch (const spacewarp::SolverError& e) {  // a numerical method that did not succeed
    std::fprintf(stderr, "numerical failure: %s\n", e.what());
    return 4;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
