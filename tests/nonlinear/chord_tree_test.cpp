#include <spacewarp/nonlinear/detail/chord_tree.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "test_util.h"

namespace spacewarp::detail {
namespace {

// Every chord in index order, the strictly nearer one kept: the result the tree must reproduce.
bool bruteForce(const ChordTree& tree, const Vec3& x, double limit2, ChordTree::Hit& hit) {
  double best = limit2;
  bool found = false;
  for (std::uint32_t k = 0; k < tree.chords(); ++k) {
    double t = 0.0;
    const double d2 = tree.distance2(x, k, t);
    if (d2 < best) {
      best = d2;
      hit = {k, t, d2};
      found = true;
    }
  }
  return found;
}

void expectSameAsBruteForce(const ChordTree& tree, const std::vector<Vec3>& queries,
                            double limit2) {
  std::size_t hits = 0;
  for (const Vec3& x : queries) {
    ChordTree::Hit fast, slow;
    const bool found = tree.nearest(x, limit2, fast);
    ASSERT_EQ(found, bruteForce(tree, x, limit2, slow)) << test::toString(x);
    if (!found) continue;
    ++hits;
    EXPECT_EQ(fast.chord, slow.chord) << test::toString(x);
    EXPECT_TRUE(fast.t == slow.t && fast.distance2 == slow.distance2) << test::toString(x);
  }
  EXPECT_GT(hits, queries.size() / 10);  // many queries land within the limit
}

// A densely sampled gentle curve (100,000 points over a unit length, as a finely tessellated
// wire) and a tight coil: the nearest chord is the brute-force one, bit for bit.
TEST(ChordTree, DenseCurvesGiveTheBruteForceNearestChord) {
  std::mt19937 rng(7);
  const std::size_t n = 100000;
  std::vector<Vec3> gentle(n), coil(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double s = static_cast<double>(k) / static_cast<double>(n - 1);
    gentle[k] = Vec3(s, 0.05 * std::sin(3.0 * s), 0.0);
    coil[k] = Vec3(0.01 * std::cos(200.0 * s), 0.01 * std::sin(200.0 * s), 0.02 * s);
  }
  const ChordTree gentleTree(gentle), coilTree(coil);
  EXPECT_EQ(gentleTree.chords(), n - 1);
  // O(n) memory: well under 200 bytes per chord.
  EXPECT_LT(gentleTree.memoryBytes(), 200 * n);
  expectSameAsBruteForce(gentleTree, test::randomPoints(rng, 300, -0.3, 1.0), 0.3 * 0.3);
  expectSameAsBruteForce(coilTree, test::randomPoints(rng, 300, -0.015, 0.025), 0.01 * 0.01);
}

// Chords repeated exactly (a polyline retracing itself) are at equal distances from every point:
// the lowest index wins, as in a scan in index order.
TEST(ChordTree, TiesGoToTheLowestChordIndex) {
  std::vector<Vec3> zigzag;
  for (int k = 0; k < 101; ++k) zigzag.push_back(k % 2 == 0 ? Vec3(0.0) : Vec3(1.0, 0.5, 0.25));
  const ChordTree tree(zigzag);
  std::mt19937 rng(3);
  const std::vector<Vec3> queries = test::randomPoints(rng, 200, -0.5, 1.5);
  expectSameAsBruteForce(tree, queries, 4.0);
  for (const Vec3& x : queries) {
    ChordTree::Hit hit;
    ASSERT_TRUE(tree.nearest(x, 4.0, hit));
    EXPECT_LE(hit.chord, 1u) << test::toString(x);  // chord 0 or its reverse, chord 1
  }
}

// Nothing within the limit: no hit (the limit prunes, it does not clip the answer).
TEST(ChordTree, NothingBeyondTheLimit) {
  const ChordTree tree(std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}});
  ChordTree::Hit hit;
  EXPECT_FALSE(tree.nearest(Vec3(0.5, -0.2, 0.0), 0.2 * 0.2, hit));
  ASSERT_TRUE(tree.nearest(Vec3(0.5, -0.2, 0.0), 0.2 * 0.2 * 1.0001, hit));
  EXPECT_EQ(hit.chord, 0u);
  EXPECT_EQ(hit.t, 0.5);
}

}  // namespace
}  // namespace spacewarp::detail
