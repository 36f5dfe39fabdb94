#include <spacewarp/core/detail/serial_blas.h>

#include <dlfcn.h>

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

}  // namespace

std::size_t blasWorkBufferBytes() {
  // OpenBLAS's BUFFER_SIZE (32 << 22 bytes on x86-64) and a page, which malloc serves by an
  // mmap rounded up to 1 MiB (measured: a 135,266,304-byte mapping).
  constexpr std::size_t kOpenBlasBuffer = (std::size_t{128} + 1) << 20;
  return blas().openblasGet ? kOpenBlasBuffer : 0;
}

SerialBlas::SerialBlas() : lock_(blasMutex()) {
  if (!blasBufferMapped) {
    if (const std::size_t bytes = blasWorkBufferBytes(); bytes > 0)
      checkMemory(static_cast<double>(bytes),
                  "the BLAS work buffer of the sparse Cholesky factorisation (OpenBLAS)");
    blasBufferMapped = true;
  }
  const Api& api = blas();
  if (api.openblasGet && api.openblasSet) {
    openblasPrevious_ = api.openblasGet();
    if (openblasPrevious_ != 1) api.openblasSet(1);
  }
  if (api.mklSetLocal) mklPrevious_ = api.mklSetLocal(1);
}

SerialBlas::~SerialBlas() {
  const Api& api = blas();
  if (api.openblasSet && openblasPrevious_ > 1) api.openblasSet(openblasPrevious_);
  if (api.mklSetLocal) api.mklSetLocal(mklPrevious_);
}

}  // namespace spacewarp::detail
