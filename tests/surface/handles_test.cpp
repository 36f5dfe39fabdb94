#include <spacewarp/surface/handles.h>

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include <spacewarp/core/errors.h>

namespace spacewarp {
namespace {

const std::vector<Vec3> kRest = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};

Mat4 translation(const Vec3& t) { return glm::translate(Mat4(1.0), t); }

TEST(ResolveHandles, AppliesMatricesAndTakesTargetsSortedByVertex) {
  std::vector<HandleRegion> regions(2);
  regions[0].vertices = {3, 1};
  regions[0].matrix = translation(Vec3(1, 2, 3));
  regions[1].vertices = {0};
  regions[1].targets = {Vec3(9, 9, 9)};
  const VertexConstraints c = resolveHandles(regions, kRest);
  EXPECT_EQ(c.vertices, (std::vector<std::uint32_t>{0, 1, 3}));
  EXPECT_EQ(c.targets, (std::vector<Vec3>{Vec3(9, 9, 9), Vec3(2, 2, 3), Vec3(1, 2, 4)}));
}

TEST(ResolveHandles, AVertexInTwoRegionsMustAgree) {
  std::vector<HandleRegion> regions(2);
  regions[0].vertices = {1};
  regions[0].matrix = Mat4(1.0);
  regions[1].vertices = {1, 2};
  regions[1].targets = {Vec3(1, 0, 0), Vec3(5, 5, 5)};
  EXPECT_EQ(resolveHandles(regions, kRest).vertices.size(), 2u);  // same target: merged
  regions[1].targets[0] = Vec3(1, 0.5, 0);
  try {
    resolveHandles(regions, kRest);
    FAIL();
  } catch (const InvalidInput& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("handle region 1"), std::string::npos) << e.what();
  }
}

TEST(ResolveHandles, RefusesMalformedRegionsNamingThem) {
  auto expectRefused = [](const HandleRegion& r, const std::string& fragment) {
    try {
      resolveHandles(std::vector<HandleRegion>{r}, kRest);
      ADD_FAILURE() << "accepted: " << fragment;
    } catch (const InvalidInput& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  HandleRegion empty;
  empty.matrix = Mat4(1.0);
  expectRefused(empty, "no vertices");
  HandleRegion outOfRange{{0, 4}, Mat4(1.0), {}};
  expectRefused(outOfRange, "index 4 is out of range");
  HandleRegion count{{0, 1}, std::nullopt, {Vec3(0)}};
  expectRefused(count, "2 vertices but 1 targets");
  HandleRegion nan{{0}, std::nullopt, {Vec3(std::nan(""))}};
  expectRefused(nan, "not finite");
  Mat4 projective(1.0);
  projective[0][3] = 0.5;
  HandleRegion notAffine{{0}, projective, {}};
  expectRefused(notAffine, "not affine");
  Mat4 inf(1.0);
  inf[3][0] = INFINITY;
  HandleRegion infinite{{0}, inf, {}};
  expectRefused(infinite, "not finite");
}

TEST(MapConstraints, MergesWeldedVerticesAndRefusesConflicts) {
  const VertexConstraints c{{0, 1, 2}, {Vec3(1), Vec3(1), Vec3(2)}};
  const std::vector<std::uint32_t> map = {5, 5, 3};
  const VertexConstraints mapped = mapConstraints(c, map, 1e-9);
  EXPECT_EQ(mapped.vertices, (std::vector<std::uint32_t>{3, 5}));
  EXPECT_EQ(mapped.targets, (std::vector<Vec3>{Vec3(2), Vec3(1)}));
  const VertexConstraints conflict{{0, 1}, {Vec3(1), Vec3(1.1)}};
  EXPECT_THROW(mapConstraints(conflict, map, 1e-9), InvalidInput);
  const VertexConstraints outside{{7}, {Vec3(1)}};
  EXPECT_THROW(mapConstraints(outside, map, 1e-9), InvalidInput);
}

}  // namespace
}  // namespace spacewarp
