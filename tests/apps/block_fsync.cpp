// Test-only LD_PRELOAD library for io_safety_cli_test.cpp: fsync() of a regular file blocks
// until a signal ends the process. spacewarp syncs an output's temporary after its last write
// and before the rename, so a test can interrupt it there, deterministically, while the
// temporary exists — however fast or slow the machine is. With SPACEWARP_BLOCK_FSYNC_NAME set,
// only files whose path contains it block (the others are synced at once), so that a run
// writing several files is interrupted at the one chosen.

#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>

extern "C" int fsync(int fd) {
  struct stat status {};
  if (::fstat(fd, &status) != 0 || !S_ISREG(status.st_mode))
    return 0;  // a directory: nothing to make durable in a test
  if (const char* name = std::getenv("SPACEWARP_BLOCK_FSYNC_NAME")) {
    char link[64], path[4096];
    std::snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    const ssize_t length = ::readlink(link, path, sizeof path - 1);
    if (length < 0) return 0;
    path[length] = '\0';
    if (std::strstr(path, name) == nullptr) return 0;
  }
  for (;;) ::pause();
}
