// Uses the installed package through its one include style (<spacewarp/...>) and checks one
// result, so a broken install (missing header, missing link dependency) fails this program.
// With files (ORIGINAL DEFORMED...), checks that each deformed soup is the original moved by
// (1, 2, 3) with the same normals: what the examples must give in TestInstallConsumer.cmake.
#include <cmath>
#include <cstdio>

#include <glm/gtc/matrix_transform.hpp>

#include <spacewarp/core/combinators.h>
#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>

namespace {

bool movedByShift(const spacewarp::PolygonSoup& original, const spacewarp::PolygonSoup& moved) {
  const spacewarp::Vec3 shift(1, 2, 3);
  if (moved.positions.size() != original.positions.size()) return false;
  if (moved.normals.size() != original.normals.size()) return false;
  for (std::size_t i = 0; i < original.positions.size(); ++i) {
    if (glm::length(moved.positions[i] - original.positions[i] - shift) > 1e-9) return false;
    if (!original.normals.empty() && glm::length(moved.normals[i] - original.normals[i]) > 1e-9)
      return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1) {
    const spacewarp::PolygonSoup original = spacewarp::readSoup(argv[1]);
    for (int i = 2; i < argc; ++i) {
      if (!movedByShift(original, spacewarp::readSoup(argv[i]))) {
        std::printf("consumer: %s is not %s moved by (1, 2, 3)\n", argv[i], argv[1]);
        return 1;
      }
    }
    std::printf("consumer: the examples' outputs are right\n");
    return 0;
  }
  const spacewarp::Mat4 shift = glm::translate(spacewarp::Mat4(1.0), spacewarp::Vec3(1, 2, 3));
  const spacewarp::AffineWarp warp(shift);
  const spacewarp::Vec3 y = warp.apply(spacewarp::Vec3(0.5));
  if (y != spacewarp::Vec3(1.5, 2.5, 3.5)) {
    std::puts("consumer: wrong result");
    return 1;
  }
  const auto box = spacewarp::makeBoxSurface(spacewarp::Vec3(0), spacewarp::Vec3(1), {2, 2, 2});
  std::printf("consumer: ok, %zu box vertices\n", box.size());
  return box.size() == 26 ? 0 : 1;
}
