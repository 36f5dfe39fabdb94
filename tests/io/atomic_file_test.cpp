#include <spacewarp/core/io/atomic_file.h>

#include <sys/resource.h>
#include <sys/stat.h>

#include <atomic>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <spacewarp/core/errors.h>
#include "io_test_util.h"

namespace spacewarp {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using test::listDirectory;
using test::readFile;
using test::TempDir;

mode_t permissionsOf(const fs::path& path) {
  struct stat status {};
  EXPECT_EQ(::stat(path.c_str(), &status), 0) << path;
  return status.st_mode & 07777;
}

/// Lowers this process's file size limit (RLIMIT_FSIZE) to `bytes` with SIGXFSZ ignored, so a
/// write past it fails with EFBIG as on a full disk; restores both on destruction.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    ::getrlimit(RLIMIT_FSIZE, &previous_);
    previousHandler_ = std::signal(SIGXFSZ, SIG_IGN);
    rlimit limit = previous_;
    limit.rlim_cur = bytes;
    EXPECT_EQ(::setrlimit(RLIMIT_FSIZE, &limit), 0);
  }
  FileSizeLimit(const FileSizeLimit&) = delete;
  FileSizeLimit& operator=(const FileSizeLimit&) = delete;
  ~FileSizeLimit() {
    ::setrlimit(RLIMIT_FSIZE, &previous_);
    std::signal(SIGXFSZ, previousHandler_);
  }

 private:
  rlimit previous_{};
  void (*previousHandler_)(int) = SIG_DFL;
};

/// The temporaries (hidden .<name>.<hex>.tmp files) in `directory`.
std::vector<std::string> temporariesIn(const fs::path& directory) {
  std::vector<std::string> found;
  for (const std::string& name : listDirectory(directory))
    if (name.starts_with('.') && name.ends_with(".tmp")) found.push_back(name);
  return found;
}

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

TEST(AtomicFileTest, WritesThroughSymbolicLinks) {
  TempDir dir;
  const fs::path target = dir.path() / "target.txt", link = dir.path() / "link.txt";
  const fs::path relative = dir.path() / "relative.txt", dangling = dir.path() / "dangling.txt";
  writeFileAtomically(target, [](std::ostream& out) { out << "old"; });
  fs::create_symlink(target, link);
  fs::create_symlink("link.txt", relative);  // a chain, relative to the link's folder
  writeFileAtomically(relative, [](std::ostream& out) { out << "new"; });
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_TRUE(fs::is_symlink(relative));
  EXPECT_EQ(readFile(target), "new");
  fs::create_symlink("made.txt", dangling);  // a dangling link creates the file it names
  writeFileAtomically(dangling, [](std::ostream& out) { out << "made"; });
  EXPECT_TRUE(fs::is_symlink(dangling));
  EXPECT_EQ(readFile(dir.path() / "made.txt"), "made");
  const fs::path loop = dir.path() / "loop.txt";
  fs::create_symlink("loop.txt", loop);
  EXPECT_THROW(writeFileAtomically(loop, [](std::ostream& out) { out << "x"; }), IoError);
  EXPECT_TRUE(temporariesIn(dir.path()).empty());
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

TEST(AtomicFileTest, ReplacedFileKeepsItsPermissions) {
  TempDir dir;
  const fs::path path = dir.path() / "out.txt";
  for (const mode_t mode : {0600, 0640, 0755, 0444}) {
    writeFileAtomically(path, [](std::ostream& out) { out << "old"; });
    ASSERT_EQ(::chmod(path.c_str(), mode), 0);
    writeFileAtomically(path, [](std::ostream& out) { out << "new"; });
    EXPECT_EQ(permissionsOf(path), mode);
    EXPECT_EQ(readFile(path), "new");
    ASSERT_EQ(::chmod(path.c_str(), 0644), 0);
  }
}

TEST(AtomicFileTest, NewFileGetsTheUmasksPermissions) {
  TempDir dir;
  const mode_t previous = ::umask(027);
  writeFileAtomically(dir.path() / "a.txt", [](std::ostream& out) { out << "a"; });
  ::umask(022);
  writeFileAtomically(dir.path() / "b.txt", [](std::ostream& out) { out << "b"; });
  ::umask(previous);
  EXPECT_EQ(permissionsOf(dir.path() / "a.txt"), 0640u);
  EXPECT_EQ(permissionsOf(dir.path() / "b.txt"), 0644u);
}

TEST(AtomicFileTest, TemporaryIsAHiddenSiblingOfTheTarget) {
  TempDir dir;
  std::vector<std::string> seen;
  writeFileAtomically(dir.path() / "out.txt",
                      [&](std::ostream&) { seen = temporariesIn(dir.path()); });
  ASSERT_EQ(seen.size(), 1u);
  // ".out.txt.<16 hex digits>.tmp" (no std::regex: GCC 12 warns falsely in it under ASan).
  const std::string prefix = ".out.txt.", suffix = ".tmp";
  ASSERT_EQ(seen[0].size(), prefix.size() + 16 + suffix.size()) << seen[0];
  EXPECT_TRUE(seen[0].starts_with(prefix) && seen[0].ends_with(suffix)) << seen[0];
  EXPECT_EQ(seen[0].find_first_not_of("0123456789abcdef", prefix.size()), prefix.size() + 16)
      << seen[0];
}

// A write that fails part way (a full disk; here a file size limit, which fails the write
// with EFBIG just as ENOSPC would) is an IoError naming the file and the system's reason,
// whether the data comes in one large block or in many small pieces, and the old file stays.
TEST(AtomicFileTest, FailingWriteKeepsTheOldFileAndSaysWhy) {
  TempDir dir;
  const fs::path path = dir.path() / "out.bin";
  const std::string old = "the previous output\n";
  const std::function<void(std::ostream&)> writers[] = {
      [](std::ostream& out) { out << std::string(1 << 20, 'x'); },
      [](std::ostream& out) {
        for (int i = 0; i < 200000; ++i) out << i << '\n';
      },
      [](std::ostream& out) {
        for (int i = 0; i < 100; ++i) out.write(std::string(30000, 'y').data(), 30000);
      },
  };
  for (const auto& writer : writers) {
    writeFileAtomically(path, [&](std::ostream& out) { out << old; });
    std::string message;
    {
      const FileSizeLimit limit(100000);
      message = test::messageOf<IoError>([&] { writeFileAtomically(path, writer); });
    }
    EXPECT_THAT(message, HasSubstr(path.string()));
    EXPECT_THAT(message, HasSubstr(std::strerror(EFBIG)));
    EXPECT_EQ(readFile(path), old);
    EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"out.bin"});
  }
}

// Even a writer that notices the failed stream itself and throws its own error is reported
// as the I/O failure it is.
TEST(AtomicFileTest, WriterThrowingOnAFailedStreamIsReportedAsTheIoError) {
  TempDir dir;
  const fs::path path = dir.path() / "out.bin";
  std::string message;
  {
    const FileSizeLimit limit(50000);
    message = test::messageOf<IoError>([&] {
      writeFileAtomically(path, [](std::ostream& out) {
        out.exceptions(std::ios::badbit | std::ios::failbit);
        out << std::string(1 << 20, 'x');
      });
    });
  }
  EXPECT_THAT(message, HasSubstr(path.string()));
  EXPECT_THAT(message, HasSubstr(std::strerror(EFBIG)));
  EXPECT_TRUE(listDirectory(dir.path()).empty());
}

// OpenVDB's writer goes back to fill in offsets: the stream must seek, and seeking must not
// lose buffered data.
TEST(AtomicFileTest, StreamIsSeekable) {
  TempDir dir;
  const fs::path path = dir.path() / "out.bin";
  writeFileAtomically(path, [](std::ostream& out) {
    out << "header:????";
    const std::streampos slot = out.tellp() - std::streamoff(4);
    out << " body " << std::string(100000, 'b');
    const std::streampos end = out.tellp();
    out.seekp(slot);
    out << "1234";
    out.seekp(end);
    out << " tail";
    EXPECT_EQ(out.tellp(), end + std::streamoff(5));
  });
  EXPECT_EQ(readFile(path), "header:1234 body " + std::string(100000, 'b') + " tail");
}

// What the CLI's signal handler relies on: the temporary of a write in progress is removed,
// the write then fails, and the old file stays. Many writes first, so that slots that were
// not released would have run out.
TEST(AtomicFileTest, RemoveAtomicTemporariesRemovesTheTemporaryInProgress) {
  TempDir dir;
  const fs::path path = dir.path() / "out.txt";
  for (int i = 0; i < 70; ++i)
    writeFileAtomically(path, [i](std::ostream& out) { out << "version " << i; });
  std::vector<std::string> before, after;
  EXPECT_THROW(writeFileAtomically(path,
                                   [&](std::ostream& out) {
                                     out << "new";
                                     before = temporariesIn(dir.path());
                                     removeAtomicTemporaries();
                                     after = temporariesIn(dir.path());
                                   }),
               IoError);
  EXPECT_EQ(before.size(), 1u);
  EXPECT_TRUE(after.empty());
  EXPECT_EQ(readFile(path), "version 69");
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"out.txt"});
  // The slot is free again for the next write.
  writeFileAtomically(path, [](std::ostream& out) { out << "next"; });
  EXPECT_EQ(readFile(path), "next");
}

// ---- writeFolderAtomically -------------------------------------------------------------

/// Writes `name` with `content` into `folder`, atomically.
void put(const fs::path& folder, const std::string& name, const std::string& content) {
  writeFileAtomically(folder / name, [&](std::ostream& out) { out << content; });
}

/// The files of `folder` with their contents.
std::map<std::string, std::string> contentOf(const fs::path& folder) {
  std::map<std::string, std::string> content;
  for (const std::string& name : listDirectory(folder)) content[name] = readFile(folder / name);
  return content;
}

TEST(AtomicFolderTest, CreatesTheFolderAndItsParents) {
  TempDir dir;
  const fs::path out = dir.path() / "parent" / "out";
  writeFolderAtomically(out, [&](const fs::path& folder) {
    EXPECT_EQ(folder.parent_path(), fs::path(dir.path() / "parent"));
    EXPECT_TRUE(folder.filename().string().starts_with(".out."));
    put(folder, "a.txt", "a");
    put(folder, "b.txt", "b");
  });
  EXPECT_EQ(contentOf(out), (std::map<std::string, std::string>{{"a.txt", "a"}, {"b.txt", "b"}}));
  EXPECT_EQ(listDirectory(dir.path() / "parent"), std::set<std::string>{"out"});
}

TEST(AtomicFolderTest, ReplacesTheOldFolderAsAWhole) {
  TempDir dir;
  const fs::path out = dir.path() / "out";
  writeFolderAtomically(out, [](const fs::path& folder) {
    put(folder, "a.txt", "old a");
    put(folder, "b.txt", "old b");
  });
  ASSERT_EQ(::chmod(out.c_str(), 0750), 0);
  writeFolderAtomically(dir.path() / "out/",
                        [](const fs::path& folder) { put(folder, "a.txt", "new a"); });
  EXPECT_EQ(contentOf(out), (std::map<std::string, std::string>{{"a.txt", "new a"}}));
  EXPECT_EQ(permissionsOf(out), 0750u);
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"out"});
}

TEST(AtomicFolderTest, WritesThroughASymbolicLink) {
  TempDir dir;
  fs::create_directory(dir.path() / "real");
  fs::create_directory_symlink("real", dir.path() / "link");
  writeFolderAtomically(dir.path() / "link", [](const fs::path& folder) { put(folder, "a", "1"); });
  EXPECT_TRUE(fs::is_symlink(dir.path() / "link"));
  EXPECT_EQ(readFile(dir.path() / "real" / "a"), "1");
  EXPECT_EQ(listDirectory(dir.path()), (std::set<std::string>{"link", "real"}));
}

// The old folder stays byte for byte whatever fails after some of the new files are complete:
// an exception of the callback, or a write past the file size limit, whose IoError names the
// file by its place in the final folder.
TEST(AtomicFolderTest, FailureKeepsTheOldFolderWhole) {
  TempDir dir;
  const fs::path out = dir.path() / "out";
  writeFolderAtomically(out, [](const fs::path& folder) {
    put(folder, "a.txt", "old a");
    put(folder, "b.txt", "old b");
  });
  const auto old = contentOf(out);
  EXPECT_THROW(writeFolderAtomically(out,
                                     [](const fs::path& folder) {
                                       put(folder, "a.txt", "new a");
                                       put(folder, "c.txt", "new c");
                                       throw InvalidInput("bad report");
                                     }),
               InvalidInput);
  EXPECT_EQ(contentOf(out), old);
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"out"});

  std::string message;
  {
    FileSizeLimit limit(4096);
    message = test::messageOf<IoError>([&] {
      writeFolderAtomically(out, [](const fs::path& folder) {
        put(folder, "a.txt", "new a");
        put(folder, "big.bin", std::string(10000, 'x'));
      });
    });
  }
  EXPECT_THAT(message, HasSubstr("'" + (out / "big.bin").string() + "'"));
  EXPECT_THAT(message, HasSubstr(std::strerror(EFBIG)));
  EXPECT_THAT(message, ::testing::Not(HasSubstr(".tmp")));
  EXPECT_EQ(contentOf(out), old);
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"out"});
}

TEST(AtomicFolderTest, RefusesWhatItCannotReplace) {
  TempDir dir;
  put(dir.path(), "file", "x");
  EXPECT_THAT(test::messageOf<IoError>(
                  [&] { writeFolderAtomically(dir.path() / "file", [](const fs::path&) {}); }),
              HasSubstr("is not a folder"));
  EXPECT_EQ(readFile(dir.path() / "file"), "x");
  EXPECT_THROW(writeFolderAtomically(dir.path() / ".", [](const fs::path&) {}), IoError);
  // The working folder (and so any of its parents) would vanish under the process.
  fs::create_directory(dir.path() / "here");
  const fs::path previous = fs::current_path();
  fs::current_path(dir.path() / "here");
  std::string message;
  try {
    message = test::messageOf<IoError>(
        [&] { writeFolderAtomically(dir.path() / "here", [](const fs::path&) {}); });
  } catch (...) {
    fs::current_path(previous);
    throw;
  }
  fs::current_path(previous);
  EXPECT_THAT(message, HasSubstr("current working folder"));
  EXPECT_EQ(listDirectory(dir.path()), (std::set<std::string>{"file", "here"}));
}

// What the CLI's signal handler relies on: the temporary folder, with the complete files and
// the temporary file in it, is removed; the write then fails and the old folder stays.
TEST(AtomicFolderTest, RemoveAtomicTemporariesRemovesTheTemporaryFolder) {
  TempDir dir;
  const fs::path out = dir.path() / "out";
  writeFolderAtomically(out, [](const fs::path& folder) { put(folder, "a.txt", "old"); });
  std::size_t before = 0;
  EXPECT_THROW(writeFolderAtomically(out,
                                     [&](const fs::path& folder) {
                                       put(folder, "a.txt", "new");
                                       writeFileAtomically(folder / "b.txt", [&](std::ostream& o) {
                                         o << "partial";
                                         before = listDirectory(folder).size();
                                         removeAtomicTemporaries();
                                       });
                                     }),
               IoError);
  EXPECT_EQ(before, 2u) << "a.txt and b.txt's temporary";
  EXPECT_EQ(contentOf(out), (std::map<std::string, std::string>{{"a.txt", "old"}}));
  EXPECT_EQ(listDirectory(dir.path()), std::set<std::string>{"out"});
  // The slots are free again.
  for (int i = 0; i < 20; ++i)
    writeFolderAtomically(out, [&](const fs::path& folder) { put(folder, "a.txt", "next"); });
  EXPECT_EQ(readFile(out / "a.txt"), "next");
}

}  // namespace
}  // namespace spacewarp
