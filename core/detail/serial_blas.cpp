#include <spacewarp/core/detail/serial_blas.h>

#include <dlfcn.h>

#include <vector>

#include <spacewarp/core/detail/memory_budget.h>

namespace spacewarp::detail {

namespace {

struct Api {
  int (*openblasGet)() = nullptr;
  void (*openblasSet)(int) = nullptr;
  int (*mklSetLocal)(int) = nullptr;
};

const Api& blas() {
  static const Api api = [] {
    Api a;
    a.openblasGet = reinterpret_cast<int (*)()>(dlsym(RTLD_DEFAULT, "openblas_get_num_threads"));
    a.openblasSet =
        reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"));
    a.mklSetLocal =
        reinterpret_cast<int (*)(int)>(dlsym(RTLD_DEFAULT, "MKL_Set_Num_Threads_Local"));
    return a;
  }();
  return api;
}

std::mutex& blasMutex() {
  static std::mutex m;
  return m;
}

// Whether a SerialBlas scope has run on this thread (so OpenBLAS's buffer for it exists, or
// another BLAS needs none).
thread_local bool blasBufferMapped = false;

// Makes OpenBLAS map this thread's work buffer now, while checkMemory says it fits, and not
// inside a factorisation whose own allocations may leave no room for it (OpenBLAS would then
// retry the mapping forever). OpenBLAS keeps the buffer for the thread's later calls. The
// product is 128 x 128 x 128: past OpenBLAS's small-matrix path, which needs no buffer.
void mapBlasWorkBuffer() {
  using Dgemm = void (*)(const char*, const char*, const int*, const int*, const int*,
                         const double*, const double*, const int*, const double*, const int*,
                         const double*, double*, const int*);
  static const auto dgemm = reinterpret_cast<Dgemm>(dlsym(RTLD_DEFAULT, "dgemm_"));
  if (dgemm == nullptr) return;
  constexpr int n = 128;
  const std::vector<double> a(std::size_t(n) * n, 0.0);
  std::vector<double> c(std::size_t(n) * n, 0.0);
  const double one = 1.0, zero = 0.0;
  dgemm("N", "N", &n, &n, &n, &one, a.data(), &n, a.data(), &n, &zero, c.data(), &n);
}

}  // namespace

std::size_t blasWorkBufferBytes() {
  // OpenBLAS's BUFFER_SIZE (32 << 22 bytes on x86-64) and a page, which malloc serves by an
  // mmap rounded up to 1 MiB (measured: a 135,266,304-byte mapping).
  constexpr std::size_t kOpenBlasBuffer = (std::size_t{128} + 1) << 20;
  return blas().openblasGet ? kOpenBlasBuffer : 0;
}

SerialBlas::SerialBlas() : lock_(blasMutex()) {
  const std::size_t bufferBytes = blasBufferMapped ? 0 : blasWorkBufferBytes();
  if (bufferBytes > 0)
    checkMemory(static_cast<double>(bufferBytes),
                "the BLAS work buffer of the sparse Cholesky factorisation (OpenBLAS)");
  const Api& api = blas();
  if (api.openblasGet && api.openblasSet) {
    openblasPrevious_ = api.openblasGet();
    if (openblasPrevious_ != 1) api.openblasSet(1);
  }
  if (api.mklSetLocal) mklPrevious_ = api.mklSetLocal(1);
  if (bufferBytes > 0) mapBlasWorkBuffer();  // single-threaded now: this thread's buffer only
  blasBufferMapped = true;
}

SerialBlas::~SerialBlas() {
  const Api& api = blas();
  if (api.openblasSet && openblasPrevious_ > 1) api.openblasSet(openblasPrevious_);
  if (api.mklSetLocal) api.mklSetLocal(mklPrevious_);
}

}  // namespace spacewarp::detail
