#include "common.h"

#include <atomic>
#include <csignal>
#include <exception>
#include <thread>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <utility>

#include <spacewarp/core/errors.h>

namespace spacewarp::python {
namespace {

PyObject* gInvalidInput = nullptr;
PyObject* gSolverError = nullptr;
PyObject* gOutOfMemory = nullptr;
PyObject* gIoError = nullptr;
PyObject* gCancelled = nullptr;

/// Set by SIGINT while library work runs; read by the progress callback of that work.
std::atomic<bool> gInterrupted{false};
struct sigaction gPreviousSigint {};

extern "C" void onSigint(int signal, siginfo_t* info, void* context) {
  gInterrupted.store(true, std::memory_order_relaxed);
  // Python's own handler only trips its flag: the KeyboardInterrupt (or the user's handler)
  // then runs in the main thread once the work has stopped.
  if (gPreviousSigint.sa_flags & SA_SIGINFO) {
    if (gPreviousSigint.sa_sigaction) gPreviousSigint.sa_sigaction(signal, info, context);
  } else if (gPreviousSigint.sa_handler != SIG_DFL && gPreviousSigint.sa_handler != SIG_IGN) {
    gPreviousSigint.sa_handler(signal);
  }
}

/// Catches SIGINT for the duration of one call from the main thread (with the GIL held, so calls
/// cannot overlap; nested calls keep the outer handler). Elsewhere, or when SIGINT is ignored or
/// kills the process (SIG_IGN, SIG_DFL), it does nothing.
class SigintGuard {
 public:
  SigintGuard() {
    // Only the main thread's calls: signal handlers run there, and a call in another thread
    // must neither see nor clear an interrupt meant for the main thread's call.
    const py::module_ threading = py::module_::import("threading");
    if (!threading.attr("current_thread")().is(threading.attr("main_thread")())) return;
    if (depth_ > 0) {
      ++depth_;
      nested_ = true;
      return;
    }
    struct sigaction current {};
    if (sigaction(SIGINT, nullptr, &current) != 0) return;
    const bool handled = (current.sa_flags & SA_SIGINFO) ||
                         (current.sa_handler != SIG_DFL && current.sa_handler != SIG_IGN);
    if (!handled) return;
    struct sigaction ours {};
    ours.sa_sigaction = onSigint;
    ours.sa_flags = SA_SIGINFO | SA_ONSTACK;
    sigemptyset(&ours.sa_mask);
    gPreviousSigint = current;
    gInterrupted.store(false, std::memory_order_relaxed);
    if (sigaction(SIGINT, &ours, nullptr) == 0) {
      depth_ = 1;
      installed_ = true;
    }
  }
  ~SigintGuard() {
    if (!nested_ && !installed_) return;
    if (--depth_ == 0) sigaction(SIGINT, &gPreviousSigint, nullptr);
  }
  SigintGuard(const SigintGuard&) = delete;
  SigintGuard& operator=(const SigintGuard&) = delete;

  bool active() const { return installed_ || nested_; }

 private:
  bool installed_ = false, nested_ = false;
  static inline int depth_ = 0;  // the main thread's, touched with the GIL held only
};

}  // namespace

void runCancellable(const py::object& progress,
                    const std::function<void(const ProgressCallback&)>& work) {
  const SigintGuard guard;
  const bool watch = guard.active();
  const bool report = progress && !progress.is_none();
  const std::thread::id mainThread = std::this_thread::get_id();
  std::optional<py::error_already_set> pythonError;
  const ProgressCallback callback = [&](std::string_view stage, double fraction) {
    // Python runs signal handlers in the main thread only: a Ctrl-C waits for a report there.
    const bool interrupted = watch && gInterrupted.load(std::memory_order_relaxed) &&
                             std::this_thread::get_id() == mainThread;
    if (!interrupted && !report) return true;
    const py::gil_scoped_acquire gil;
    if (pythonError) return false;
    if (interrupted) {
      gInterrupted.store(false, std::memory_order_relaxed);
      // The SIGINT handler (KeyboardInterrupt by default) runs now; if it does not raise, the
      // work goes on, as an interrupted Python loop would.
      if (PyErr_CheckSignals() != 0) {
        pythonError.emplace();
        return false;
      }
    }
    if (!report) return true;
    try {
      const py::object result = progress(py::str(stage.data(), stage.size()), fraction);
      if (result.is_none()) return true;
      const int truth = PyObject_IsTrue(result.ptr());  // False (or np.False_, 0) stops
      if (truth < 0) throw py::error_already_set();
      return truth != 0;
    } catch (py::error_already_set& e) {
      pythonError.emplace(std::move(e));
      return false;
    }
  };
  try {
    withoutGil([&] { work(watch || report ? callback : ProgressCallback{}); });
  } catch (const Cancelled&) {
    if (pythonError) throw std::move(*pythonError);
    throw;
  }
}

void forEachPointCancellable(std::size_t n, const char* stage,
                             const std::function<void(std::size_t)>& f) {
  runCancellable(py::none(), [&](const ProgressCallback& callback) {
    ProgressTracker tracker(callback, stage, n);
    forEachBlock(n, std::size_t{1} << 14, tracker, [&](std::size_t begin, std::size_t count) {
      tbb::parallel_for(tbb::blocked_range<std::size_t>(begin, begin + count, 256),
                        [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) f(i);
                        });
    });
  });
}

void warnAll(const std::vector<std::string>& messages) {
  for (const std::string& message : messages) {
    if (PyErr_WarnEx(PyExc_UserWarning, message.c_str(), 2) != 0) throw py::error_already_set();
  }
}

void registerErrors(py::module_& m) {
  const auto make = [&](const char* name, PyObject* bases, const char* doc) {
    const std::string qualified = std::string("spacewarp.") + name;
    PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases, nullptr);
    if (!type) throw py::error_already_set();
    m.add_object(name, py::handle(type));
    return type;
  };
  gInvalidInput = make("InvalidInput", PyExc_ValueError,
                       "Input that violates a documented precondition: NaN coordinates, an empty "
                       "set, an open cage, a degenerate lattice, a malformed rig. A ValueError.");
  gSolverError = make("SolverError", PyExc_RuntimeError,
                      "A numerical method that produced no result: a singular system, a failed "
                      "factorisation, an inverse that did not converge. A RuntimeError.");
  const py::tuple memoryBases =
      py::make_tuple(py::handle(gSolverError), py::handle(PyExc_MemoryError));
  gOutOfMemory =
      make("OutOfMemory", memoryBases.ptr(),
           "Memory that ran out inside TetGen or CHOLMOD (which report it by a status code). "
           "A SolverError and a MemoryError. (A job that its memory estimate refuses before "
           "it starts is InvalidInput, naming what to make smaller.)");
  gIoError = make("IoError", PyExc_OSError,
                  "A file that could not be read or written, or whose content is malformed; the "
                  "message names the file. An OSError.");
  gCancelled =
      make("Cancelled", PyExc_RuntimeError,
           "Work stopped because a progress callback returned False. Nothing was written.");
  py::register_exception_translator([](std::exception_ptr error) {
    try {
      if (error) std::rethrow_exception(error);
    } catch (const OutOfMemory& e) {
      PyErr_SetString(gOutOfMemory, e.what());
    } catch (const InvalidInput& e) {
      PyErr_SetString(gInvalidInput, e.what());
    } catch (const SolverError& e) {
      PyErr_SetString(gSolverError, e.what());
    } catch (const IoError& e) {
      PyErr_SetString(gIoError, e.what());
    } catch (const Cancelled& e) {
      PyErr_SetString(gCancelled, e.what());
    }
  });
}

}  // namespace spacewarp::python
