// Tests of the typed errors (core/errors.h): namingFile keeps each type, OutOfMemory included.

#include <spacewarp/core/errors.h>

#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "test_util.h"

using namespace spacewarp;
using ::testing::HasSubstr;

namespace {

// OutOfMemory is a SolverError: namingFile rethrew it as a plain SolverError, which the command
// line reports as a numerical failure (exit 4) instead of out of memory (exit 3).
TEST(NamingFile, KeepsEachTypeAndPrefixesTheName) {
  const std::string oom = test::messageOf<OutOfMemory>([] {
    namingFile("cage.obj", []() -> int { throw OutOfMemory("TetGen ran out of memory"); });
  });
  EXPECT_EQ(oom, "cage.obj: TetGen ran out of memory");
  EXPECT_THAT(test::messageOf<SolverError>(
                  [] { namingFile("cage.obj", []() -> int { throw SolverError("singular"); }); }),
              HasSubstr("cage.obj: singular"));
  EXPECT_THAT(test::messageOf<InvalidInput>(
                  [] { namingFile("cage.obj", []() -> int { throw InvalidInput("open cage"); }); }),
              HasSubstr("cage.obj: open cage"));
  EXPECT_THAT(test::messageOf<IoError>([] {
                namingFile("cage.obj", []() -> int { throw IoError("cage.obj: truncated"); });
              }),
              HasSubstr("cage.obj: truncated"));
}

}  // namespace
