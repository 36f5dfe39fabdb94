#pragma once
// Progress reporting and cancellation for long work (binding, harmonic solves, volume warps).
// The library calls a user callback with a stage name and the fraction done; the callback
// returns false to cancel, and the work then stops by throwing Cancelled.

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>

namespace spacewarp {

/// Called with the stage ("bind", "tetrahedralise", "solve", "warp volume", ...) and the
/// fraction of that stage done, in [0, 1]. Return false to cancel. Calls are serialised (never
/// concurrent) but may come from any thread; keep the callback cheap.
using ProgressCallback = std::function<bool(std::string_view stage, double fraction)>;

/// Thrown when a ProgressCallback returned false. Work that throws it leaves its outputs
/// unchanged (the library's functions are all-or-nothing).
class Cancelled : public std::runtime_error {
 public:
  explicit Cancelled(const std::string& stage) : std::runtime_error(stage + ": cancelled") {}
};

/// Counts units of work done by many threads and forwards the fraction to a callback, at most
/// once per percent so that reporting costs nothing measurable. A null callback makes every
/// call a no-op apart from one relaxed atomic add.
class ProgressTracker {
 public:
  /// `total` units make up the stage; reports 0 at once. Keeps a reference to `callback`,
  /// which must outlive the tracker.
  ProgressTracker(const ProgressCallback& callback, std::string stage, std::size_t total)
      : callback_(callback), stage_(std::move(stage)), total_(total) {
    report(0.0);
  }

  /// Adds `units` done (thread-safe). Throws Cancelled if the callback asked to stop, now or
  /// earlier.
  void advance(std::size_t units = 1) {
    if (!callback_) return;
    const std::size_t done = done_.fetch_add(units, std::memory_order_relaxed) + units;
    const std::size_t percent = total_ ? done * 100 / total_ : 100;
    std::size_t last = lastPercent_.load(std::memory_order_relaxed);
    while (percent > last) {
      if (lastPercent_.compare_exchange_weak(last, percent, std::memory_order_relaxed)) {
        report(static_cast<double>(percent) / 100.0);
        break;
      }
    }
    if (cancelled_.load(std::memory_order_relaxed)) throw Cancelled(stage_);
  }

  /// Reports completion (fraction 1). Throws Cancelled if the callback asks to stop.
  void finish() {
    report(1.0);
    if (cancelled_.load(std::memory_order_relaxed)) throw Cancelled(stage_);
  }

  /// Reports the fraction done so far once more, for work that runs long between units (a
  /// display stays alive, a cancel is seen), then throws Cancelled if the callback asks to stop.
  void poll() {
    const std::size_t done = done_.load(std::memory_order_relaxed);
    report(total_ ? std::min(1.0, static_cast<double>(done) / static_cast<double>(total_)) : 0.0);
    check();
  }

  /// Throws Cancelled if the callback has asked to stop.
  void check() const {
    if (cancelled_.load(std::memory_order_relaxed)) throw Cancelled(stage_);
  }

 private:
  void report(double fraction) {
    if (!callback_) return;
    const std::lock_guard lock(mutex_);
    if (!callback_(stage_, fraction)) cancelled_.store(true, std::memory_order_relaxed);
  }

  const ProgressCallback& callback_;
  std::string stage_;
  std::size_t total_;
  std::atomic<std::size_t> done_{0};
  std::atomic<std::size_t> lastPercent_{0};
  std::atomic<bool> cancelled_{false};
  std::mutex mutex_;
};

/// Runs fn(begin, count) on consecutive blocks of at most `block` items covering [0, n), one
/// after the other (each block is meant to be parallel inside), advancing `tracker` by each
/// block's size, then finishes the tracker. `block` = 0 means a single block. The blocks give
/// a display its steps and a cancel its chances, and bound the memory of per-block buffers.
template <class Fn>
void forEachBlock(std::size_t n, std::size_t block, ProgressTracker& tracker, Fn&& fn) {
  if (block == 0) block = std::max<std::size_t>(n, 1);
  for (std::size_t begin = 0; begin < n; begin += block) {
    const std::size_t count = std::min(block, n - begin);
    fn(begin, count);
    tracker.advance(count);
  }
  tracker.finish();
}

}  // namespace spacewarp
