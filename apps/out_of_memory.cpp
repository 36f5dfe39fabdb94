#include "apps/out_of_memory.h"

#include <dlfcn.h>
#include <fcntl.h>
#include <pthread.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <iterator>
#include <new>
#include <system_error>

#include <spacewarp/core/errors.h>
#include <spacewarp/core/io/atomic_file.h>
#include "apps/cli_context.h"

namespace spacewarp::cli {

namespace {

// Two buffers, so that a new activity is written into the one no reader is pointed at.
constexpr std::size_t kActivityCapacity = 200;
char activityBuffers[2][kActivityCapacity + 1];
std::atomic<const char*> activity{"starting spacewarp"};
std::atomic<bool> reported{false};

// Appends `text` to `line` (capacity `size`, NUL-terminated), control characters as '?'.
void append(char* line, std::size_t size, const char* text) {
  std::size_t length = std::strlen(line);
  for (; *text != '\0' && length + 1 < size; ++text, ++length) {
    const auto byte = static_cast<unsigned char>(*text);
    line[length] = byte < 0x20 || byte == 0x7f ? '?' : *text;
  }
  line[length] = '\0';
}

std::terminate_handler previousTerminate = nullptr;

// std::terminate's handler: an out-of-memory exception that no handler caught (a worker thread's,
// a destructor's during unwinding, a noexcept function's) ends the process as exitOutOfMemory
// does; anything else goes to the previous handler (libstdc++'s, which names the exception and
// aborts).
[[noreturn]] void onTerminate() {
  if (const std::exception_ptr current = std::current_exception()) {
    try {
      std::rethrow_exception(current);
    } catch (const std::bad_alloc&) {
      exitOutOfMemory();
    } catch (const OutOfMemory& e) {
      exitOutOfMemory(e.what());
    } catch (const std::system_error& e) {
      if (isOutOfResources(e.code())) exitOutOfMemory(e.what());
    } catch (...) {
    }
  }
  if (previousTerminate) previousTerminate();
  std::abort();
}

// The environment OpenBLAS and libgomp read when they are loaded (see out_of_memory.h).
constexpr const char* kLibrarySettings[] = {"OPENBLAS_NUM_THREADS=1", "OMP_THREAD_LIMIT=1"};

// Whether the environment entry `entry` ("NAME=value") sets the variable that `setting` does.
bool sameName(const char* entry, const char* setting) {
  const std::size_t name = static_cast<std::size_t>(std::strchr(setting, '=') - setting);
  return std::strncmp(entry, setting, name + 1) == 0;
}

// Whether an allocation can fail for want of address space: under an address-space or
// data-size limit (ulimit -v, -d), or with strict overcommit accounting. Elsewhere malloc's
// reservations succeed (memory runs out later, when pages are touched) and OpenBLAS's buffers
// are always granted. Only system calls: no library is initialised yet.
bool allocationsCanFail() {
  struct rlimit limit {};
  for (const int resource : {RLIMIT_AS, RLIMIT_DATA})
    if (::getrlimit(resource, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) return true;
  char mode = '0';
  if (const int fd = ::open("/proc/sys/vm/overcommit_memory", O_RDONLY | O_CLOEXEC); fd >= 0) {
    if (::read(fd, &mode, 1) != 1) mode = '0';
    ::close(fd);
  }
  return mode == '2';
}

// Runs before any shared library's initialiser (.preinit_array; executables only). The
// environment cannot simply be changed here: libc's own initialiser, which runs next, points
// `environ` back at the process's original array (measured: OpenBLAS's getenv then saw no
// OPENBLAS_NUM_THREADS). So where allocations can fail and the settings are not there already,
// the executable starts itself again with them (same arguments, same process): no library
// initialiser has run yet, so no thread has started and nothing is lost but the time to load
// the libraries again (about 60 ms, which runs without limits are spared). Should that fail
// (no /proc), it runs as it is.
void beforeLibraries(int, char** argv, char** envp) {
  previousTerminate = std::set_terminate(onTerminate);
  if (!allocationsCanFail()) return;
  std::size_t entries = 0, present = 0;
  for (; envp[entries] != nullptr; ++entries)
    for (const char* setting : kLibrarySettings)
      if (std::strcmp(envp[entries], setting) == 0) ++present;
  if (present == std::size(kLibrarySettings)) return;
  const std::size_t settings = std::size(kLibrarySettings);
  auto** environment =
      static_cast<const char**>(std::malloc((entries + settings + 1) * sizeof(char*)));
  if (environment == nullptr) return;
  std::size_t kept = 0;
  for (std::size_t i = 0; i < entries; ++i) {
    bool replaced = false;
    for (const char* setting : kLibrarySettings) replaced = replaced || sameName(envp[i], setting);
    if (!replaced) environment[kept++] = envp[i];
  }
  for (const char* setting : kLibrarySettings) environment[kept++] = setting;
  environment[kept] = nullptr;
  ::execve("/proc/self/exe", argv, const_cast<char* const*>(environment));
  std::free(environment);
}

__attribute__((used, section(".preinit_array"))) void (*preinit)(int, char**,
                                                                 char**) = beforeLibraries;

}  // namespace

void setActivity(std::string_view text) {
  char* buffer = activityBuffers[activity.load() == activityBuffers[0] ? 1 : 0];
  const std::size_t length = std::min(text.size(), kActivityCapacity);
  std::memcpy(buffer, text.data(), length);
  buffer[length] = '\0';
  activity.store(buffer);
}

bool isOutOfResources(int errorNumber) { return errorNumber == ENOMEM || errorNumber == EAGAIN; }

bool isOutOfResources(const std::error_code& code) {
  return (code.category() == std::generic_category() ||
          code.category() == std::system_category()) &&
         isOutOfResources(code.value());
}

int reportOutOfMemory(const char* detail) {
  if (!reported.exchange(true)) {
    char line[1024] = "spacewarp: error: out of memory while ";
    append(line, sizeof line, activity.load());
    append(line, sizeof line, ": ");
    append(line, sizeof line,
           detail != nullptr ? detail : "the input is too large for the memory available");
    const std::size_t length = std::min(std::strlen(line), sizeof line - 2);
    line[length] = '\n';
    line[length + 1] = '\0';
    // One write, no stdio: another thread may hold stderr's lock, and nothing here allocates.
    [[maybe_unused]] const ssize_t written = ::write(STDERR_FILENO, line, std::strlen(line));
  }
  return kBadInput;
}

void exitOutOfMemory(const char* detail) {
  reportOutOfMemory(detail);
  removeAtomicTemporaries();
  ::_exit(kBadInput);
}

}  // namespace spacewarp::cli

// Every library's pthread_create (TBB's, libgomp's, std::thread's in libstdc++) reaches this
// definition first, since the executable comes first in the dynamic linker's lookup; it calls
// the next one (libc's, or a sanitizer's) and ends the process with the out-of-memory line when
// no thread could be made: the callers could only exit(1) or throw from a static constructor.
extern "C" int pthread_create(pthread_t* thread, const pthread_attr_t* attributes,
                              void* (*start)(void*), void* argument) noexcept {
  using Create = int (*)(pthread_t*, const pthread_attr_t*, void* (*)(void*), void*);
  static const auto next = reinterpret_cast<Create>(::dlsym(RTLD_NEXT, "pthread_create"));
  if (next == nullptr) return ENOSYS;
  const int error = next(thread, attributes, start, argument);
  if (spacewarp::cli::isOutOfResources(error))
    spacewarp::cli::exitOutOfMemory("the system could not start another thread");
  return error;
}
