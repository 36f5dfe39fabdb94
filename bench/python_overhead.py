#!/usr/bin/env python3
"""What calling spacewarp through Python costs over C++, measured side by side in one run.

For a 1M-point twist (Warp.__call__ against Warp::applyBatch) and a 1M-point mean-value bind
(Coordinates.bind against constructing a Binding), on the same arrays in the same process,
alternating the two: the medians and their ratio. The MVC cage is the armadillo cage of
../shared/data when present, else a subdivided box (96 triangles).

    PYTHONPATH=build/python /usr/bin/python3 bench/python_overhead.py [--points N] [--repeats K]
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import spacewarp as sw
from spacewarp import _spacewarp as ext


def box_cage(n: int = 4) -> sw.Cage:
    """The surface of [-1, 1]^3 cut into n x n quads per side."""
    ticks = np.linspace(-1.0, 1.0, n + 1)
    vertices, index, faces = [], {}, []

    def vertex(p):
        key = tuple(np.round(p, 12))
        if key not in index:
            index[key] = len(vertices)
            vertices.append(p)
        return index[key]

    for axis in range(3):
        for side in (-1.0, 1.0):
            u, v = [a for a in range(3) if a != axis]
            for i in range(n):
                for j in range(n):
                    quad = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        p = np.zeros(3)
                        p[axis], p[u], p[v] = side, ticks[i + di], ticks[j + dj]
                        quad.append(vertex(p))
                    faces.append(quad)
    return sw.Cage(np.array(vertices), faces)  # Cage orients the faces outward


def armadillo_cage():
    path = Path(__file__).resolve().parents[2] / "shared" / "data" / "ju2005-armadillo" / "bounding_mesh.obj"
    return sw.Cage.from_file(path) if path.exists() else None


def measure(name, cpp, python, repeats):
    cpp_times, py_times = [], []
    for _ in range(repeats):
        cpp_times.append(cpp())
        start = time.perf_counter()
        python()
        py_times.append(time.perf_counter() - start)
    c, p = statistics.median(cpp_times), statistics.median(py_times)
    print(f"{name:<44} C++ {c * 1e3:9.1f} ms   Python {p * 1e3:9.1f} ms   Python/C++ {p / c:6.3f}")
    return p / c


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    rng = np.random.default_rng(42)

    points = rng.uniform(-1.0, 1.0, (args.points, 3))
    twist = sw.Twist(axis=(0.3, 0.4, 1.0), rate=np.pi / 2)
    measure(f"twist, {args.points:,} points", lambda: ext._cpp_apply_seconds(twist, points),
            lambda: twist(points), args.repeats)

    cage = armadillo_cage()
    label = "armadillo cage" if cage is not None else "box cage"
    cage = cage or box_cage()
    lo, hi = cage.vertices.min(0), cage.vertices.max(0)
    inside = np.empty((0, 3))
    while len(inside) < args.points:  # rejection sampling with the winding number
        candidates = rng.uniform(lo, hi, (args.points, 3))
        inside = np.concatenate([inside, candidates[cage.contains(candidates)]])
    inside = np.ascontiguousarray(inside[: args.points])
    mvc = sw.MeanValue(cage)
    measure(f"mvc bind, {len(inside):,} points ({label})", lambda: ext._cpp_bind_seconds(mvc, inside),
            lambda: mvc.bind(inside), args.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
