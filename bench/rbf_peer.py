#!/usr/bin/env python3
"""spacewarp's RBF fit and evaluation against SciPy's RBFInterpolator, in one run.

The same centers (uniform in the unit cube) and displacements, the same kernel (r^3, spacewarp's
"triharmonic", SciPy's "cubic") and polynomial (degree 1). Fit: RbfWarp(centers, targets)
against RBFInterpolator(centers, displacements, kernel="cubic", degree=1); evaluation: the
fitted warp on N points against the interpolator's __call__ on them. The runs alternate and
each figure is the median of --repeats; the ratio is SciPy's time over spacewarp's. Also
prints how far the two fits' displacements at the evaluation points differ (relative to the
largest displacement), and the fit alone for --big centers when asked (the 20,000-center case).
Skips SciPy, saying so, when it is not installed.

    PYTHONPATH=build/python /usr/bin/python3 bench/rbf_peer.py [--centers 2000]
        [--points 1000000] [--repeats 5] [--big 20000]
"""

import argparse
import os
import statistics
import time

import numpy as np

import spacewarp as sw

try:
    from scipy.interpolate import RBFInterpolator
except ImportError:  # the peer is optional
    RBFInterpolator = None


def timed(f):
    start = time.perf_counter()
    result = f()
    return time.perf_counter() - start, result


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--centers", type=int, default=2000)
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--big", type=int, default=0, help="also time one fit of this many centers")
    args = parser.parse_args()

    rng = np.random.default_rng(19)
    centers = rng.random((args.centers, 3))
    displacement = 0.1 * (rng.random((args.centers, 3)) - 0.5)
    targets = centers + displacement
    points = rng.random((args.points, 3))
    print(f"{args.centers} centers, {args.points} evaluation points, medians of {args.repeats}; "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}; "
          f"load average {os.getloadavg()[0]:.1f}")
    if RBFInterpolator is None:
        print("SciPy is not installed: the peer is skipped (apt-get install python3-scipy)")

    fits = {"spacewarp": [], "scipy": []}
    evals = {"spacewarp": [], "scipy": []}
    ours = theirs = None
    for _ in range(args.repeats):
        t, warp = timed(lambda: sw.RbfWarp(centers, targets))
        fits["spacewarp"].append(t)
        t, moved = timed(lambda: warp(points))
        evals["spacewarp"].append(t)
        ours = moved - points
        if RBFInterpolator is not None:
            t, interp = timed(lambda: RBFInterpolator(centers, displacement, kernel="cubic",
                                                      degree=1))
            fits["scipy"].append(t)
            t, theirs = timed(lambda: interp(points))
            evals["scipy"].append(t)

    def row(name, times):
        ms = {k: statistics.median(v) for k, v in times.items() if v}
        line = f"{name:<10} spacewarp {ms['spacewarp'] * 1e3:9.1f} ms"
        if "scipy" in ms:
            line += f"   scipy {ms['scipy'] * 1e3:9.1f} ms   ratio {ms['scipy'] / ms['spacewarp']:.2f}x"
        print(line)

    row("fit", fits)
    row("evaluate", evals)
    if theirs is not None:
        diff = np.abs(ours - theirs).max() / np.abs(displacement).max()
        print(f"max |spacewarp - scipy| displacement at the points: {diff:.2e} of the largest")
    if args.big:
        big = rng.random((args.big, 3))
        t, warp = timed(lambda: sw.RbfWarp(big, big + 0.01))
        print(f"fit of {args.big} centers: spacewarp {t:.2f} s (one run)")


if __name__ == "__main__":
    main()
