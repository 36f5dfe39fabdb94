// Test-only LD_PRELOAD library for io_safety_cli_test.cpp: fsync() of a regular file blocks
// until a signal ends the process. spacewarp syncs an output's temporary after its last write
// and before the rename, so a test can interrupt it there, deterministically, while the
// temporary exists — however fast or slow the machine is.

#include <sys/stat.h>
#include <unistd.h>

extern "C" int fsync(int fd) {
  struct stat status {};
  if (::fstat(fd, &status) == 0 && S_ISREG(status.st_mode))
    for (;;) ::pause();
  return 0;  // a directory: nothing to make durable in a test
}
