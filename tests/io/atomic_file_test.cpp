#include "core/io/atomic_file.h"

#include <atomic>
#include <filesystem>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/errors.h"
#include "io_test_util.h"

namespace spacewarp {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using test::listDirectory;
using test::readFile;
using test::TempDir;

TEST(AtomicFileTest, WritesTheFile) {
  TempDir dir;
  const fs::path path = dir.path() / "out.txt";
  writeFileAtomically(path, [](std::ostream& out) {
    out << "hello\n" << std::string(1, '\0') << "binary";
  });
  EXPECT_EQ(readFile(path), std::string("hello\n\0binary", 13));
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"out.txt"});
}

TEST(AtomicFileTest, ReplacesAnExistingFile) {
  TempDir dir;
  const fs::path path = dir.path() / "out.txt";
  writeFileAtomically(path, [](std::ostream& out) { out << "a much longer first version"; });
  writeFileAtomically(path, [](std::ostream& out) { out << "second"; });
  EXPECT_EQ(readFile(path), "second");
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"out.txt"});
}

TEST(AtomicFileTest, ThrowingCallbackLeavesNothingBehind) {
  TempDir dir;
  const fs::path path = dir.path() / "out.txt";
  EXPECT_THROW(writeFileAtomically(path,
                                   [](std::ostream& out) {
                                     out << std::string(100000, 'x');
                                     throw std::logic_error("callback failed");
                                   }),
               std::logic_error);
  EXPECT_TRUE(listDirectory(dir.path()).empty());
}

TEST(AtomicFileTest, ThrowingCallbackKeepsTheOldFile) {
  TempDir dir;
  const fs::path path = dir.path() / "out.txt";
  writeFileAtomically(path, [](std::ostream& out) { out << "old"; });
  EXPECT_THROW(writeFileAtomically(path,
                                   [](std::ostream& out) {
                                     out << "partial new content";
                                     throw InvalidInput("bad soup");
                                   }),
               InvalidInput);
  EXPECT_EQ(readFile(path), "old");
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"out.txt"});
}

TEST(AtomicFileTest, FailedStreamThrowsIoErrorNamingThePath) {
  TempDir dir;
  const fs::path path = dir.path() / "out.txt";
  writeFileAtomically(path, [](std::ostream& out) { out << "old"; });
  EXPECT_THAT(test::messageOf<IoError>([&] {
                writeFileAtomically(path, [](std::ostream& out) {
                  out << "new";
                  out.setstate(std::ios::badbit);
                });
              }),
              HasSubstr(path.string()));
  EXPECT_EQ(readFile(path), "old");
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"out.txt"});
}

TEST(AtomicFileTest, MissingDirectoryThrowsIoError) {
  TempDir dir;
  const fs::path path = dir.path() / "missing" / "out.txt";
  EXPECT_THAT(test::messageOf<IoError>(
                  [&] { writeFileAtomically(path, [](std::ostream& out) { out << "x"; }); }),
              HasSubstr(path.string()));
  EXPECT_TRUE(listDirectory(dir.path()).empty());
}

TEST(AtomicFileTest, PathUnderARegularFileThrowsIoError) {
  TempDir dir;
  writeFileAtomically(dir.path() / "file", [](std::ostream& out) { out << "x"; });
  EXPECT_THROW(writeFileAtomically(dir.path() / "file" / "out.txt", [](std::ostream&) {}), IoError);
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"file"});
}

TEST(AtomicFileTest, RenameOntoADirectoryFailsCleanly) {
  TempDir dir;
  fs::create_directory(dir.path() / "taken");
  fs::create_directory(dir.path() / "taken" / "child");
  EXPECT_THROW(writeFileAtomically(dir.path() / "taken", [](std::ostream& out) { out << "x"; }),
               IoError);
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"taken"});
}

TEST(AtomicFileTest, RelativePathInTheCurrentDirectory) {
  TempDir dir;
  const fs::path previous = fs::current_path();
  fs::current_path(dir.path());
  try {
    writeFileAtomically("relative.txt", [](std::ostream& out) { out << "here"; });
  } catch (...) {
    fs::current_path(previous);
    throw;
  }
  fs::current_path(previous);
  EXPECT_EQ(readFile(dir.path() / "relative.txt"), "here");
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"relative.txt"});
}

TEST(AtomicFileTest, ConcurrentWritersNeverProduceAMixedFile) {
  TempDir dir;
  const fs::path path = dir.path() / "shared.txt";
  std::vector<std::thread> threads;
  std::atomic<int> failures{0};
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < 20; ++i) {
        try {
          writeFileAtomically(path, [t](std::ostream& out) {
            out << std::string(50000, static_cast<char>('a' + t));
          });
        } catch (...) {
          ++failures;
        }
      }
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(failures.load(), 0);
  const std::string content = readFile(path);
  ASSERT_EQ(content.size(), 50000u);
  EXPECT_EQ(content, std::string(50000, content[0]));
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"shared.txt"});
}

}  // namespace
}  // namespace spacewarp
