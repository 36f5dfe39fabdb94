#pragma once
// Runs a scope with a single-threaded BLAS, so that sparse Cholesky factorisations and solves
// (CHOLMOD's supernodes call dgemm, dsyrk, dpotrf, dtrsm, ...) round the same way for any
// OPENBLAS_NUM_THREADS: a multithreaded BLAS splits that work, and so its rounding, by the
// thread count. OpenBLAS's process-wide thread count is set to 1 for the scope and restored
// after it; MKL's thread-local count likewise; other BLAS libraries are left alone. A
// process-wide mutex serialises the scopes, so two solves on two threads do not restore each
// other's setting mid-factorisation. The BLAS is looked up at run time (dlsym), so nothing
// links against a particular BLAS.
//
// OpenBLAS maps a work buffer of 128 MiB for a thread on its first level-3 call there, and when
// that allocation fails it retries forever (a hang, not an error). So the first scope on each
// thread checks that the buffer fits (detail::checkMemory) and has OpenBLAS map it at once, so
// that it exists before the factorisation's own allocations can take its room.

#include <cstddef>
#include <mutex>

namespace spacewarp::detail {

/// The memory OpenBLAS maps for a thread's BLAS work buffer (BUFFER_SIZE, 128 MiB on x86-64,
/// plus malloc's rounding) when OpenBLAS is the BLAS of this process; 0 for any other BLAS.
std::size_t blasWorkBufferBytes();

class SerialBlas {
 public:
  /// Throws InvalidInput (detail::checkMemory) if this is the thread's first scope and
  /// blasWorkBufferBytes() exceed the memory available.
  SerialBlas();
  ~SerialBlas();
  SerialBlas(const SerialBlas&) = delete;
  SerialBlas& operator=(const SerialBlas&) = delete;

 private:
  std::lock_guard<std::mutex> lock_;
  int openblasPrevious_ = 1;
  int mklPrevious_ = 0;
};

}  // namespace spacewarp::detail
