#include <spacewarp/core/detail/serial_blas.h>

#include <dlfcn.h>

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

}  // namespace

SerialBlas::SerialBlas() : lock_(blasMutex()) {
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
