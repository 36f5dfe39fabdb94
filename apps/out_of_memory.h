#pragma once
// Every way the spacewarp process can run out of memory ends the same way: one line
// "spacewarp: error: out of memory while <activity>: <detail>" on stderr, the temporaries of the
// outputs being written removed, exit code 3 (DESIGN.md: bad input, here input too large for
// the machine). Jobs too large for the memory available are mostly refused before they start
// (core/detail/memory_budget.h), and a std::bad_alloc that reaches main() is reported there;
// out_of_memory.cpp handles the rest, which used to abort (exit 134), exit 1 or hang:
//
// - A std::bad_alloc (or OutOfMemory, or a thread that could not be started) thrown where no
//   handler catches it: from a destructor during unwinding (OpenVDB's Tree::clear() allocates,
//   so a grid destroyed while a bad_alloc propagates throws again), from a noexcept function or
//   from a thread's own function. std::terminate() then runs; its handler is replaced.
// - A thread that cannot be created (pthread_create fails with EAGAIN or ENOMEM, typically
//   because its stack does not fit under an address-space limit): TBB and libgomp end the
//   process with exit(1), and log4cplus (which OpenVDB loads) throws from a static constructor,
//   before main(). The executable defines pthread_create, which every library's call reaches
//   first, and ends the process as above when the real one fails so.
// - OpenBLAS starts its worker threads when it is loaded, before main(); each mallocs a 128 MiB
//   buffer and retries forever when that fails, and the process hung at exit joining them
//   (even `spacewarp --version` under `ulimit -v 250000`). Setting OPENBLAS_NUM_THREADS in
//   main() is too late, and so is setting it before any library initialises (a .preinit_array
//   function: libc's initialiser then restores the original environment). So that function
//   starts the executable again (execve, same arguments and process) with OPENBLAS_NUM_THREADS=1
//   (spacewarp runs every BLAS call on one thread anyway: core/detail/serial_blas.h) and
//   OMP_THREAD_LIMIT=1 (CHOLMOD's supernodal factorisation asks libgomp for a team of 4
//   threads, whatever OMP_NUM_THREADS says) in its environment, unless they are there already.
//   It does so only where allocations can fail (an address-space or data-size limit, strict
//   overcommit): elsewhere OpenBLAS's buffers are always granted, and runs are spared the time
//   of loading the libraries twice. Children of the process inherit both settings.
//
// Only the executable uses this file: a library must not replace process-wide handlers.

#include <string>
#include <string_view>
#include <system_error>

namespace spacewarp::cli {

/// What the process is doing, for the message: "running 'spacewarp deform'". Kept in a fixed
/// buffer (at most 200 characters), so that reporting allocates nothing. Call from the main
/// thread only. Before the first call: "starting spacewarp".
void setActivity(std::string_view activity);

/// Whether an errno value means that the system ran out of memory or of threads (ENOMEM,
/// EAGAIN).
bool isOutOfResources(int errorNumber);

/// The same for an error code of the generic or system category: a std::system_error from
/// std::thread, for instance.
bool isOutOfResources(const std::error_code& code);

/// Prints "spacewarp: error: out of memory while <activity>: <detail>" (detail: "the input is
/// too large for the memory available" when null) as one line (control characters replaced),
/// unless an out-of-memory line was printed already, and returns 3, the exit code. For main().
int reportOutOfMemory(const char* detail = nullptr);

/// reportOutOfMemory(), then removes the temporaries of the outputs being written and ends the
/// process at once with exit code 3. Allocates nothing; callable from any thread.
[[noreturn]] void exitOutOfMemory(const char* detail = nullptr);

}  // namespace spacewarp::cli
