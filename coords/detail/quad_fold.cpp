#include <spacewarp/coords/detail/quad_fold.h>

#include <cmath>
#include <string>

#include <spacewarp/core/errors.h>

namespace spacewarp::detail {

void checkQuadUnfolded(std::span<const Vec3> vertices, std::span<const std::uint32_t> face,
                       std::size_t f, const char* method, const std::string& cageName) {
  const Vec3 q[4] = {vertices[face[0]], vertices[face[1]], vertices[face[2]], vertices[face[3]]};
  // The Newell normal of a quad is half the cross product of its diagonals.
  const Vec3 newell = glm::cross(q[2] - q[0], q[3] - q[1]);
  const double length = glm::length(newell);
  bool folded = !(length > 0.0);
  // At corner c the patch normal is (q_{c+1} − q_c) × (q_{c−1} − q_c) (a positive multiple of
  // ξ_u × ξ_v there, whatever the corner's place in (u, v)).
  for (int c = 0; c < 4 && !folded; ++c) {
    const Vec3 next = q[(c + 1) % 4] - q[c], prev = q[(c + 3) % 4] - q[c];
    const double scale = glm::length(next) * glm::length(prev) * length;
    folded = !(glm::dot(glm::cross(next, prev), newell) > 1e-12 * scale);
  }
  // The centre: (ξ_u × ξ_v)(½, ½), the cross product of the mid-edge vectors.
  const Vec3 eu = 0.5 * (q[1] - q[0] + q[2] - q[3]), ev = 0.5 * (q[3] - q[0] + q[2] - q[1]);
  folded = folded || !(glm::dot(glm::cross(eu, ev), newell) > 0.0);
  if (!folded) return;
  throw InvalidInput(cageName + ": " + method + ": face " + std::to_string(f) + " (vertices " +
                     std::to_string(face[0]) + ", " + std::to_string(face[1]) + ", " +
                     std::to_string(face[2]) + ", " + std::to_string(face[3]) +
                     ") folds over: its bilinear patch is not one-to-one (a concave or degenerate "
                     "quad, or one twisted past flat), so points near it would see surface that "
                     "is not there; split it into triangles");
}

}  // namespace spacewarp::detail
