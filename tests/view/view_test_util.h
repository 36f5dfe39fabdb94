#pragma once
// Shared inputs of the viewer's tests: a folder per test with a box cage around a smaller box
// model, poses of that cage, and rig files of every control kind.

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <spacewarp/core/io/mesh_io.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/rig/rig.h>

#include "apps/view/view_session.h"

namespace spacewarp::test {

/// The largest distance between corresponding points, over the model's bounding-box diagonal.
inline double relativeGap(std::span<const Vec3> a, std::span<const Vec3> b,
                          std::span<const Vec3> model) {
  EXPECT_EQ(a.size(), b.size());
  BoundingBox box;
  for (const Vec3& p : model) {
    box.min = glm::min(box.min, p);
    box.max = glm::max(box.max, p);
  }
  double worst = 0.0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i)
    worst = std::max(worst, glm::length(a[i] - b[i]));
  return worst / box.diagonal();
}

/// A sway of the cage: points turn about z by an angle growing with z and shift along x.
inline std::vector<Vec3> sway(std::span<const Vec3> rest, double amount = 0.3) {
  std::vector<Vec3> out;
  for (const Vec3& p : rest) {
    const double t = amount * (p.z + 1.0) / 2.0;
    out.emplace_back(std::cos(t) * p.x - std::sin(t) * p.y + 0.5 * t,
                     std::sin(t) * p.x + std::cos(t) * p.y, p.z * (1.0 + 0.1 * t));
  }
  return out;
}

/// A rigid motion: a turn of `angle` about the axis (1, 2, 3) and a shift.
inline std::vector<Vec3> rigid(std::span<const Vec3> rest, double angle = 0.4) {
  const Vec3 k = glm::normalize(Vec3(1, 2, 3));
  std::vector<Vec3> out;
  for (const Vec3& p : rest)
    out.push_back(p * std::cos(angle) + glm::cross(k, p) * std::sin(angle) +
                  k * glm::dot(k, p) * (1 - std::cos(angle)) + Vec3(0.3, -0.2, 0.1));
  return out;
}

/// x → −x: every method that reproduces linear maps inverts the whole model.
inline std::vector<Vec3> mirror(std::span<const Vec3> rest) {
  std::vector<Vec3> out;
  for (const Vec3& p : rest) out.emplace_back(-p.x, p.y, p.z);
  return out;
}

/// A folder per test with cage.obj (a box of 12 vertices around the origin) and model.obj (a
/// smaller box surface inside it), removed afterwards.
class ViewFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("spacewarp_view_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    writeSoup(makeBoxSurface(Vec3(-1, -1, -1.5), Vec3(1, 1, 1.5), glm::ivec3(1, 1, 2)),
              dir_ / "cage.obj");
    model_ = makeBoxSurface(Vec3(-0.6, -0.5, -1.2), Vec3(0.6, 0.5, 1.2), glm::ivec3(3, 3, 6));
    writeSoup(model_, dir_ / "model.obj");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name, std::ios::binary) << text;
    return dir_ / name;
  }

  /// The session over model.obj and cage.obj; harmonic with few tets, to stay quick.
  view::ViewSession cageSession(const std::string& method = "") {
    view::ViewSessionOptions options;
    options.method = method;
    options.harmonicTets = 3000;
    return view::ViewSession::withCage(dir_ / "model.obj", dir_ / "cage.obj", options);
  }

  /// The positions that `spacewarp deform --rig` computes from a rig file: the rig's warp
  /// applied to the rest model.
  std::vector<Vec3> deformedByRig(const std::filesystem::path& rig) {
    const Rig built = loadRig(rig);
    std::vector<Vec3> out(model_.positions.size());
    built.warp->applyBatch(model_.positions, out);
    return out;
  }

  std::filesystem::path dir_;
  PolygonSoup model_;
};

/// Handles of the handle rigs: the 8 corners of a box around the model.
inline std::vector<Vec3> boxCorners() {
  std::vector<Vec3> out;
  for (int i = 0; i < 8; ++i)
    out.emplace_back(i & 1 ? 0.9 : -0.9, i & 2 ? 0.8 : -0.8, i & 4 ? 1.4 : -1.4);
  return out;
}

inline std::string jsonOf(std::span<const Vec3> points) {
  nlohmann::json out = nlohmann::json::array();
  for (const Vec3& p : points) out.push_back({p.x, p.y, p.z});
  return out.dump();
}

}  // namespace spacewarp::test
