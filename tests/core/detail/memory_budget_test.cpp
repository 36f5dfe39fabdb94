// Tests of the memory estimate checks (core/detail/memory_budget.h): the limits they read, the
// cap, and the message that names the parameter and the estimate.

#include <spacewarp/core/detail/memory_budget.h>

#include <sys/resource.h>

#include <fstream>
#include <limits>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include "test_util.h"

using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

constexpr std::size_t kNoCap = std::numeric_limits<std::size_t>::max();

TEST(MemoryBudget, FormatsBytesWithDecimalUnits) {
  EXPECT_EQ(detail::formatBytes(0), "0 bytes");
  EXPECT_EQ(detail::formatBytes(999), "999 bytes");
  EXPECT_EQ(detail::formatBytes(1500), "1.5 kB");
  EXPECT_EQ(detail::formatBytes(2.5e9), "2.5 GB");
  EXPECT_EQ(detail::formatBytes(1.6e10), "16 GB");
}

TEST(MemoryBudget, TheCapBoundsWhatIsAvailable) {
  detail::setMemoryCap(std::size_t{1} << 20);
  EXPECT_LE(detail::availableMemory(), std::size_t{1} << 20);
  EXPECT_NO_THROW(detail::checkMemory(1000.0, "small"));
  const std::string message =
      test::messageOf<InvalidInput>([] { detail::checkMemory(3e6, "'spacing' (9 nodes)"); });
  detail::setMemoryCap(kNoCap);
  EXPECT_THAT(message, HasSubstr("'spacing' (9 nodes) needs about 3 MB of memory"));
  EXPECT_THAT(message, HasSubstr("1.05 MB available"));
}

// The process's data size (VmData in /proc/self/status), in bytes.
std::size_t dataSize() {
  std::ifstream in("/proc/self/status");
  std::string key;
  std::size_t kb = 0;
  while (in >> key) {
    if (key == "VmData:" && in >> kb) return kb * 1024;
  }
  return 0;
}

TEST(MemoryBudget, SeesALoweredDataLimit) {
#ifdef SPACEWARP_SANITIZED
  GTEST_SKIP() << "AddressSanitizer's allocator cannot run under a lowered data limit";
#endif
  rlimit saved{};
  ASSERT_EQ(getrlimit(RLIMIT_DATA, &saved), 0);
  const std::size_t used = dataSize();
  ASSERT_GT(used, 0u);
  const std::size_t headroom = std::size_t{64} << 20;
  if (saved.rlim_max != RLIM_INFINITY && saved.rlim_max < used + headroom)
    GTEST_SKIP() << "the hard data limit is already lower";
  rlimit lowered = saved;
  lowered.rlim_cur = used + headroom;
  ASSERT_EQ(setrlimit(RLIMIT_DATA, &lowered), 0);
  const std::size_t available = detail::availableMemory();
  const std::string message =
      test::messageOf<InvalidInput>([] { detail::checkMemory(1e9, "'resolution' 1000"); });
  ASSERT_EQ(setrlimit(RLIMIT_DATA, &saved), 0);
  EXPECT_LE(available, headroom);
  EXPECT_GT(available, headroom / 2);  // what the test itself allocated since is small
  EXPECT_THAT(message, HasSubstr("'resolution' 1000 needs about 1 GB of memory"));
}

}  // namespace
