#pragma once
// The iteration of ArapEditor and CageArapEditor: alternate the global step (the unknowns for
// the current rotations) and the local step (the best rotations, and the energy, for the
// unknowns), with Anderson acceleration kept only when it lowers the energy, so that the
// energies never rise.

#include <cmath>
#include <vector>

#include <Eigen/Core>

#include <spacewarp/core/progress.h>
#include <spacewarp/surface/detail/anderson.h>

namespace spacewarp::detail {

struct LocalGlobalOptions {
  int maxIterations = 0;
  double relativeTolerance = 0.0;
  int accelerationWindow = 0;
  /// The energy's rounding level: at or below it there is nothing left to minimise.
  double floor = 0.0;
};

struct LocalGlobalReport {
  std::vector<double> energies;
  int iterations = 0;
  bool converged = false;
};

/// Minimises from `x`, whose local step has been done with energy `e`. `local(x)` does the local
/// step and returns the energy, `global(x)` the global step from the current rotations;
/// `save()`/`restore()` keep the rotations across a step that is given up; `flat(x)` views x as
/// one vector (for the acceleration). Reports each iteration to `tracker`.
template <class X, class Local, class Global, class Save, class Restore, class Flat>
LocalGlobalReport minimiseLocalGlobal(X& x, double e, const LocalGlobalOptions& o,
                                      ProgressTracker& tracker, Local&& local, Global&& global,
                                      Save&& save, Restore&& restore, Flat&& flat) {
  LocalGlobalReport report;
  report.energies.push_back(e);
  AndersonAccelerator anderson(static_cast<std::size_t>(o.accelerationWindow));
  while (report.iterations < o.maxIterations && !report.converged) {
    if (std::abs(e) <= o.floor) {
      report.converged = true;
      break;
    }
    save();
    X plain = global(x);
    X next = plain;
    flat(next) = anderson.next(flat(x), flat(plain));
    double eNext = local(next);
    if (!(eNext < e) && next != plain) {  // the extrapolation did not help: the plain step
      anderson.reset();
      next = std::move(plain);
      eNext = local(next);
    }
    if (eNext > e) {  // rounding: the exact steps cannot raise it; keep the better state
      restore();
      report.converged = true;
      break;
    }
    ++report.iterations;
    report.converged = e - eNext <= o.relativeTolerance * std::abs(e) + o.floor;
    x = std::move(next);
    e = eNext;
    report.energies.push_back(e);
    tracker.advance();
  }
  if (std::abs(e) <= o.floor) report.converged = true;
  return report;
}

}  // namespace spacewarp::detail
