// Uses the installed package through both include styles and checks one result, so a
// broken install (missing header, missing link dependency) fails this program.
#include <cstdio>

#include <glm/gtc/matrix_transform.hpp>

#include <core/primitives.h>
#include <spacewarp/core/combinators.h>

int main() {
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
