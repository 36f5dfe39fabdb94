// The progress/cancel callback: fractions reported in order from many threads, throttled, and
// a cancel that stops the work without touching its output.

#include <spacewarp/core/progress.h>

#include <atomic>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <spacewarp/core/deform.h>
#include <spacewarp/core/primitives.h>
#include <spacewarp/core/twist.h>

namespace spacewarp {
namespace {

TEST(ProgressTracker, ReportsIncreasingFractionsFromZeroToOneAtMostOncePerPercent) {
  std::vector<double> seen;
  const ProgressCallback callback = [&](std::string_view stage, double fraction) {
    EXPECT_EQ(stage, "count");
    seen.push_back(fraction);  // calls are serialised: no lock needed here
    return true;
  };
  ProgressTracker tracker(callback, "count", 1'000'000);
  tbb::parallel_for(0, 1'000'000, [&](int) { tracker.advance(); });
  tracker.finish();
  ASSERT_GE(seen.size(), 3u);
  EXPECT_LE(seen.size(), 102u);
  EXPECT_EQ(seen.front(), 0.0);
  EXPECT_EQ(seen.back(), 1.0);
  for (std::size_t i = 1; i < seen.size(); ++i) EXPECT_LE(seen[i - 1], seen[i]);
}

TEST(ProgressTracker, NullCallbackIsANoOp) {
  const ProgressCallback none;
  ProgressTracker tracker(none, "nothing", 10);
  for (int i = 0; i < 20; ++i) tracker.advance();
  EXPECT_NO_THROW(tracker.finish());
}

TEST(ProgressTracker, CancelThrowsAtTheNextStep) {
  const ProgressCallback stopHalfway = [](std::string_view, double f) { return f < 0.5; };
  ProgressTracker tracker(stopHalfway, "stage", 100);
  int done = 0;
  try {
    for (; done < 100; ++done) tracker.advance();
    FAIL() << "not cancelled";
  } catch (const Cancelled& e) {
    EXPECT_STREQ(e.what(), "stage: cancelled");
  }
  EXPECT_EQ(done, 49);  // the 50th advance reported 0.5 and was refused
}

TEST(Deform, ReportsProgressAndLeavesTheSetUnchangedWhenCancelled) {
  PointSet points = makeRandomPoints(Vec3(-1), Vec3(1), 300'000, 5);
  const PointSet before = points;
  TwistOptions p;
  p.rate = 1.0;
  const TwistWarp twist(p);

  std::atomic<int> calls = 0;
  PointSet reported = points;
  deform(twist, reported, [&](std::string_view stage, double) {
    EXPECT_EQ(stage, "deform");
    ++calls;
    return true;
  });
  EXPECT_GE(calls.load(), 2);
  PointSet plain = points;
  deform(twist, plain);
  EXPECT_EQ(reported.positions, plain.positions);

  EXPECT_THROW(deform(twist, points, [](std::string_view, double f) { return f < 0.3; }),
               Cancelled);
  EXPECT_EQ(points.positions, before.positions);
}

}  // namespace
}  // namespace spacewarp
