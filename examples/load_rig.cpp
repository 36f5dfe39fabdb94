// Deforms a polygon soup or point cloud with any rig file, the JSON the spacewarp tool reads
// (README.md, "Rigs"):
//
//   load_rig RIG.json INPUT OUTPUT
//
// Exit codes follow the spacewarp tool: 0 success, 3 bad input or file, 4 numerical failure,
// 1 other.
#include <cstdio>
#include <exception>

#include <spacewarp/core/deform.h>
#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/rig/rig.h>

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: %s RIG.json INPUT OUTPUT\n", argv[0]);
    return 2;
  }
  try {
    // The same checks as the tool: unknown keys, duplicate keys, missing files are errors
    // that name the rig file and the key.
    const spacewarp::Rig rig = spacewarp::loadRig(argv[1]);
    spacewarp::PolygonSoup soup = spacewarp::readSoup(argv[2]);
    spacewarp::deform(*rig.warp, soup);
    spacewarp::writeSoup(soup, argv[3]);
    std::printf("deformed %zu vertices -> %s\n", soup.positions.size(), argv[3]);
    return 0;
  } catch (const spacewarp::IoError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 3;
  } catch (const spacewarp::InvalidInput& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 3;
  } catch (const spacewarp::SolverError& e) {
    std::fprintf(stderr, "numerical failure: %s\n", e.what());
    return 4;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
