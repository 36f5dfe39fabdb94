#include <spacewarp/core/detail/rotation.h>

#include <random>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

namespace spacewarp::detail {
namespace {

double orthogonalityError(const Mat3& r) {
  const Mat3 e = glm::transpose(r) * r - Mat3(1.0);
  return std::sqrt(glm::dot(e[0], e[0]) + glm::dot(e[1], e[1]) + glm::dot(e[2], e[2]));
}

double gain(const Mat3& r, const Mat3& b) {
  return glm::dot(r[0], b[0]) + glm::dot(r[1], b[1]) + glm::dot(r[2], b[2]);
}

Mat3 randomMatrix(std::mt19937& rng, double flatness) {
  std::normal_distribution<double> g;
  Mat3 b(0.0);
  for (int k = 0; k < 6; ++k) {
    const Vec3 e(g(rng), g(rng), flatness * g(rng));
    b += glm::outerProduct(e + 0.3 * Vec3(g(rng), g(rng), g(rng)), e);
  }
  return b;
}

// From guesses near and far (up to the opposite rotation) and for matrices of rank 3, nearly 2
// and with negative determinant: a rotation, maximising tr(Rᵀ b) as closestRotation does.
TEST(ClosestRotationNear, AgreesWithClosestRotationFromAnyGuess) {
  std::mt19937 rng(3);
  std::normal_distribution<double> g;
  for (double flatness : {1.0, 1e-3, 1e-9}) {
    for (int trial = 0; trial < 2000; ++trial) {
      Mat3 b = randomMatrix(rng, flatness);
      if (trial % 5 == 0) b[2] = -b[2];  // det < 0: the best rotation is not the polar factor
      const Mat3 exact = closestRotation(b);
      for (double spread : {1e-6, 1e-2, 0.5, 3.0}) {
        const Vec3 axis = glm::normalize(Vec3(g(rng), g(rng), g(rng)));
        const Mat3 guess = Mat3(glm::rotate(glm::dmat4(1.0), spread, axis)) * exact;
        const Mat3 r = closestRotationNear(b, guess);
        ASSERT_LT(orthogonalityError(r), 1e-14);
        ASSERT_GT(glm::determinant(r), 0.0);
        const double scale = std::abs(gain(exact, b)) + 1e-300;
        ASSERT_GE(gain(r, b), gain(exact, b) - 1e-14 * scale)
            << "flatness " << flatness << " trial " << trial << " spread " << spread;
      }
    }
  }
}

TEST(ClosestRotationNear, IsExactForARotatedSymmetricPositiveMatrix) {
  const Mat3 q = Mat3(glm::rotate(glm::dmat4(1.0), 1.1, glm::normalize(Vec3(1, -2, 0.5))));
  const Mat3 s(Vec3(3, 0.2, 0.1), Vec3(0.2, 2, -0.3), Vec3(0.1, -0.3, 0.5));
  const Mat3 r = closestRotationNear(q * s, Mat3(1.0));
  for (int c = 0; c < 3; ++c) EXPECT_LT(glm::length(r[c] - q[c]), 1e-14);
  const Mat3 again = closestRotationNear(q * s, q);
  for (int c = 0; c < 3; ++c) EXPECT_LT(glm::length(again[c] - q[c]), 1e-15);
}

}  // namespace
}  // namespace spacewarp::detail
